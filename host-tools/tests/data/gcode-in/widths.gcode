; widths.gcode: a 12 mm perimeter loop at 0.9 mm in tool 0, then 0.8 mm infill lines in tool 1,
; E as 1.75 mm filament (relative, M83), sections as PrusaSlicer's flow model gives them:
; 0.9 mm -> 0.4627 mm^2, 0.8 mm -> 0.4027 mm^2 at 0.6 mm layers
G90
M83
G1 Z0.6 F600
G1 X50 Y50 F3000
T0
;TYPE:Perimeter
G1 X62 Y50 E2.30864 F1200
G1 X62 Y62 E2.30864 F1200
G1 X50 Y62 E2.30864 F1200
G1 X50 Y50 E2.30864 F1200
T1
;TYPE:Internal infill
G1 X51.2 Y51.2 F3000
G1 X60.8 Y51.2 E1.60744 F1200
G1 X60.8 Y52.8 F3000
G1 X51.2 Y52.8 E1.60744 F1200
G1 X51.2 Y54.4 F3000
G1 X60.8 Y54.4 E1.60744 F1200
G1 X60.8 Y56.0 F3000
G1 X51.2 Y56.0 E1.60744 F1200
G1 X51.2 Y57.6 F3000
G1 X60.8 Y57.6 E1.60744 F1200
G1 X60.8 Y59.2 F3000
G1 X51.2 Y59.2 E1.60744 F1200
; filament_diameter = 1.75,1.75
