set terminal pngcairo size 1100,650 noenhanced font ',10'
set datafile missing '?'
set key outside right
set grid ytics
set output 'stages.png'
set title 'Time per stage (median GPU ms), llvmpipe (LLVM 15.0.6, 256 bits), llvmpipe Mesa 22.3.6 (LLVM 15.0.6)'
set style data histogram
set style histogram rowstacked
set style fill solid 0.8 border -1
set boxwidth 0.7
set xtics rotate by -45
set ylabel 'ms'
plot 'stages.dat' using 2:xtic(1) title 'raster', '' using 3 title 'pip', '' using 4 title 'compaction', '' using 5 title 'trace', '' using 6 title 'shading', '' using 7 title 'transfers', '' using 8 title 'other'
