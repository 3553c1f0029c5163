; square-rel-e.gcode with valve commands instead of T: M42 P, SET_PIN, M106 P, RRF's G1 P<bitmap>
G90
M83
G1 Z0.6 F600
G1 X50 Y50 F3000
M42 P0 S1
G1 X60 Y50 E1.0
SET_PIN PIN=dollop_valve0 VALUE=1
G1 X60 Y60 E1.0
M107 P0
M106 ; a cooling fan without P: skipped
G1 X62 Y62
M106 P1 S255
SET_PIN PIN=dollop_valve1 VALUE=0
G1 X62 Y70 E0.8 P2
G1 X50 Y70 E1.2
