set -x
for s in ring knot plate3 ringx; do
  ./neus-aug synth --mesh $s.ply --up-axis +z --out ${s}scene > synth-$s.log 2>&1
  /usr/bin/time -f "%e s" ./neus-aug reconstruct ${s}scene --preset fast --seed 0 --quiet --out r-$s-s0 > r-$s-s0.log 2>&1
done
