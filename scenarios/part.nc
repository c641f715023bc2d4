(small part contour, 25 x 20 mm: two corners rounded by G03, one by G02, one sharp)
G17 G21 G90
G00 X0 Y0
G01 X20 Y0 F1000
G03 X25 Y5 I0 J5
G01 X25 Y15
G03 X20 Y20 R5
G01 X5 Y20
G02 X0 Y15 R5
G01 X0 Y0
G04 P0.1
M30
