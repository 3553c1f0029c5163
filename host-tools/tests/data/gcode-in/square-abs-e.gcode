; a 10 mm square: two sides in tool 0, then tool 1 after a travel
G21
G90
M82
G28 ; homing is skipped
M104 S0
G1 Z0.6 F600
G92 E0
G1 X50 Y50 F3000
T0
G1 X60 Y50 E1.0
G1 X60 Y60 E2.0
G92 E0
G1 X62 Y62
T1
G1 X62 Y70 E0.8
G1 X50 Y70 E2.0
