# gnuplot script written by fesbench study: predicted vs measured knee angle, leg 1
set terminal png size 900,500
set termoption noenhanced
set yrange [-20:140]
set xlabel 't (s)'
set ylabel 'knee angle (deg flexion)'
set key outside right
set grid
set output 'plot_step.png'
set title 'Leg 1, input step: predicted vs measured'
plot 'plot_step.dat' using 1:2 with lines lw 2 title 'measured', '' using 1:3 with lines title 'sequential_rb1', '' using 1:4 with lines title 'simultaneous_rb1', '' using 1:5 with lines title 'free_swing_rb1', '' using 1:6 with lines title 'rapid'
set output 'plot_ramp.png'
set title 'Leg 1, input ramp: predicted vs measured'
plot 'plot_ramp.dat' using 1:2 with lines lw 2 title 'measured', '' using 1:3 with lines title 'sequential_rb1', '' using 1:4 with lines title 'simultaneous_rb1', '' using 1:5 with lines title 'free_swing_rb1', '' using 1:6 with lines title 'rapid'
set output 'plot_sine.png'
set title 'Leg 1, input sine: predicted vs measured'
plot 'plot_sine.dat' using 1:2 with lines lw 2 title 'measured', '' using 1:3 with lines title 'sequential_rb1', '' using 1:4 with lines title 'simultaneous_rb1', '' using 1:5 with lines title 'free_swing_rb1', '' using 1:6 with lines title 'rapid'
set output 'plot_rb1.png'
set title 'Leg 1, input rb1: predicted vs measured'
plot 'plot_rb1.dat' using 1:2 with lines lw 2 title 'measured', '' using 1:3 with lines title 'sequential_rb1', '' using 1:4 with lines title 'simultaneous_rb1', '' using 1:5 with lines title 'free_swing_rb1', '' using 1:6 with lines title 'rapid'
set output 'plot_rb2.png'
set title 'Leg 1, input rb2: predicted vs measured'
plot 'plot_rb2.dat' using 1:2 with lines lw 2 title 'measured', '' using 1:3 with lines title 'sequential_rb1', '' using 1:4 with lines title 'simultaneous_rb1', '' using 1:5 with lines title 'free_swing_rb1', '' using 1:6 with lines title 'rapid'
