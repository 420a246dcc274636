cd /work/exp10
./run.sh nb0 relief 0 m05 --set model.loss.mask=0.5
./run.sh nb0 blocks 0 m05 --set model.loss.mask=0.5
./run.sh nb0 relief 0 m2 --set model.loss.mask=2.0
./run.sh nb0 blocks 0 m2 --set model.loss.mask=2.0
