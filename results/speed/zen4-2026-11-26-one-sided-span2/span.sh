for s in blob torus double-torus plate thin relief blocks rods; do
  /usr/bin/time -f "%e s" ./neus-aug-span reconstruct $s --preset fast --seed 0 --quiet --out r-sp2-$s-s0 --set model.render.fd_central_every=4 --set model.render.fd_one_sided_span=2.0 > r-sp2-$s-s0.log 2>&1
done
