set datafile separator ','
set terminal pngcairo size 1200,480
set output 'budget.png'
set multiplot layout 1,2
set title 'median frame time against geometry budget'
set xlabel 'budget (MiB; unlimited: the whole geometry)'
set ylabel 'ms'
set logscale x 2
plot for [m in 'afsm rh'] 'budget_summary.csv' using (strcol(1) eq m ? $3 : 1/0):4 with linespoints title m
unset logscale x
set title 'bytes streamed per frame along the camera path'
set xlabel 'frame'
set ylabel 'MiB'
plot for [b in ' 3029156 757289'] 'budget.csv' using ((strcol(1) eq 'afsm' && $3 == real(b)) ? $5 : 1/0):($8/1048576) with points pt 7 title 'afsm '.sprintf('%.1f MiB', real(b)/1048576)
unset multiplot
