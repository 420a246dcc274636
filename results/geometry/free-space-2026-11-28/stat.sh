#!/bin/bash
# stat NAME BIN args : depth-map stats only, dump to dumps/NAME
name=$1; bin=$2; shift 2
NEUS_DD=1 NEUS_DD_EXIT=1 NEUS_DD_DUMP=dumps/$name $bin reconstruct sc/cup400 --preset fast --seed 0 --quiet --out r/tmpstat --force --set train.depth.weight=5 "$@" > dumps/$name.log 2>&1
/work/cupvenv/bin/python py/src_err.py dumps/$name
