while pgrep -f span.sh > /dev/null; do sleep 5; done
for s in thin torus double-torus blob plate relief blocks rods; do
  /usr/bin/time -f "%e s" ./neus-aug-span reconstruct $s --preset fast --seed 1 --quiet --out r-sp2-$s-s1 --set model.render.fd_central_every=4 --set model.render.fd_one_sided_span=2.0 > r-sp2-$s-s1.log 2>&1
done
for s in ringx plate3 knot; do
  /usr/bin/time -f "%e s" ./neus-aug reconstruct ${s}scene --preset fast --seed 1 --quiet --out r-$s-s1 > r-$s-s1.log 2>&1
done
