; square-rel-e.gcode in a frame whose origin G92 puts at machine (40, 40)
G90
M83
G1 Z0.6 F600
G1 X50 Y50 F3000
G92 X10 Y10
T0
G1 X20 Y10 E1.0
G1 X20 Y20 E1.0
G1 X22 Y22
T1
G1 X22 Y30 E0.8
G1 X10 Y30 E1.2
