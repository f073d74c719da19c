set terminal pngcairo size 1100,650 noenhanced font ',10'
set datafile missing '?'
set key outside right
set grid ytics
set output 'methods.png'
set title 'Hard shadows per method (median ms per frame), llvmpipe (LLVM 15.0.6, 256 bits), llvmpipe Mesa 22.3.6 (LLVM 15.0.6)'
set style data histogram
set style histogram cluster gap 1
set style fill solid 0.8 border -1
set logscale y
set ylabel 'ms'
plot 'methods.dat' using 2:xtic(1) title 'sm', '' using 3 title 'srt', '' using 4 title 'frt', '' using 5 title 'Embree oracle (CPU)', '' using 6 title 'afsm'
