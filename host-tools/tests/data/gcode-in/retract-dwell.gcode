; a bead, retract, lift, travel, lower, unretract, dwell, a second bead
G90
M83
G1 Z0.6 F600
G1 X50 Y50
G1 X60 Y50 E1.0
G1 E-0.5 F1800
G1 Z1.6
G1 X70 Y50
G1 Z0.6
G1 E0.5
G4 P250
G4 S1.5
M73 P50
M140 S0
G1 X80 Y50 E1.0
