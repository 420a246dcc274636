#!/usr/bin/env bash
cd /work/exp11
for g in /work/exp10/torus-soh/runs/* /work/exp10/dt-hull/runs/*; do [ -d $g ] && ./rex.sh $g 2; done
for r in rods-soh-s1 rods-soh-s2 thin-hull-s1 rods-soh-s0 thin-hull-s0; do ./rex.sh /work/exp10/runs/$r 2; done
for s in blob blocks relief plate cup; do ./run.sh nv2 $s 0 vis; done
for s in blocks relief plate blob cup; do ./run.sh nv2 $s 1 vis; done
