#!/usr/bin/env bash
# The hard-shape suite: synthesise each scene, print its floor, reconstruct it at a
# preset for the given seeds, and print one line per run (Chamfer sum against the floor, genus
# of the written mesh's largest component against the truth, components before and after
# clean-up, held-out normal error and silhouette IoU). The floor and the true genus come from the
# scene's meta.json (written by `synth`); a scene made by an older simulator lacks them ("?").
# Extra arguments go to every `reconstruct` (e.g. --set ...). `neus-aug study hard` runs the
# same suite as a study with a report.
#
#   scripts/hard_suite.sh WORKDIR [PRESET] [SEEDS] [-- EXTRA RECONSTRUCT ARGS]
#   scripts/hard_suite.sh /tmp/hard fast "0 1 2"
#
# Scenes: $SCENES (default "blob torus double-torus plate rods thin"). About 3–10 minutes per run
# at the fast preset on 2 cores.
set -euo pipefail
work=${1:?usage: hard_suite.sh WORKDIR [PRESET] [SEEDS] [-- ARGS]}
preset=${2:-fast}
seeds=${3:-0}
shift $(( $# < 3 ? $# : 3 ))
[ "${1:-}" = "--" ] && shift
scenes=${SCENES:-"blob torus double-torus plate rods thin"}
here=$(cd "$(dirname "$0")/.." && pwd)
bin=${NEUS_AUG:-$here/target/release/neus-aug}
[ -x "$bin" ] || (cd "$here" && cargo build --release --bin neus-aug)
mkdir -p "$work/runs"
for s in $scenes; do
  if [ ! -f "$work/scenes/$s/meta.json" ]; then
    "$bin" synth "$s" --out "$work/scenes/$s" --quiet | grep '^floor' | sed "s/^/$s /"
  fi
  for seed in $seeds; do
    out="$work/runs/$s-$preset-s$seed"
    [ -f "$out/metrics.json" ] || "$bin" reconstruct "$work/scenes/$s" --preset "$preset" \
      --seed "$seed" --quiet --out "$out" "$@" > "$out.log" 2>&1 || { echo "$s s$seed failed: $out.log"; continue; }
    python3 - "$out/metrics.json" "$work/scenes/$s/meta.json" "$s" "$seed" <<'PY'
import json, sys
m = json.load(open(sys.argv[1])); c = m["chamfer"] or {}; me = m["mesh"]
meta = json.load(open(sys.argv[2]))
truth = meta.get("mesh_genus", "?")
floor = (meta.get("floor") or {}).get("chamfer_sum")
chamfer = c.get("chamfer_sum")
f = lambda x, d=2: "n/a" if x is None else f"{x:.{d}f}"
ratio = None if chamfer is None or not floor else chamfer / floor
genus = me.get("largest_genus", me.get("genus"))
print(f"{sys.argv[3]:13s} s{sys.argv[4]}  chamfer {f(chamfer, 3)} mm (floor {f(floor, 3)}, "
      f"ratio {f(ratio)})  genus {genus} (truth {truth})  components "
      f"{me.get('raw_components')} -> {me['components']}  normal error "
      f"{f(m.get('normal_error_deg'))} deg  IoU {f(m.get('mask_iou_heldout'))}  "
      f"{m['timings_s']['total']:.0f} s")
PY
  done
done
