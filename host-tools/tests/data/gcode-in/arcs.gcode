; a full circle of radius 10 about (100, 100), counter-clockwise, then a clockwise
; half circle of radius 5 by R, in tool 1
G90
M83
G1 Z0.6
G1 X110 Y100
G3 X110 Y100 I-10 J0 E6.0
T1
G2 X100 Y100 R5 E1.5
