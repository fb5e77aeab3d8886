( A 40 mm square with a 15 mm circle inside it, for the plotter or the mill )
G21 G90 G64
G0 X10 Y10
G1 X50 Y10 F3000   ; 50 mm/s
G1 X50 Y50
G1 X10 Y50
G1 X10 Y10
G0 X45 Y30
G2 X45 Y30 I-15 J0 F2400 ; a full circle, clockwise
G0 X0 Y0
M2
