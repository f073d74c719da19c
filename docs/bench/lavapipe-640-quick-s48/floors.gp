set terminal pngcairo size 1100,650 noenhanced font ',10'
set datafile missing '?'
set key outside right
set grid ytics
set terminal pngcairo size 1800,700 noenhanced font ',9'
set output 'floors.png'
set title 'Each stage against its floor (time / floor, 1 = at the floor), llvmpipe (LLVM 15.0.6, 256 bits), llvmpipe Mesa 22.3.6 (LLVM 15.0.6)'
set style data histogram
set style fill solid 0.8 border -1
set xtics rotate by -70 font ',7'
set logscale y
set ylabel 'time / floor'
set boxwidth 0.8
plot 'floors.dat' using 2:xtic(1) notitle
