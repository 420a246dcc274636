#!/usr/bin/env bash
# The hard-shape suite of issue 13: synthesise each scene, print its floor, reconstruct it at a
# preset for the given seeds, and print one line per run (Chamfer sum against the floor, genus
# of the written mesh against the truth, components before and after clean-up, held-out normal
# error and silhouette IoU). Extra arguments go to every `reconstruct` (e.g. --set ...).
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
declare -A genus=([blob]=0 [torus]=1 [double-torus]=2 [plate]=0 [rods]=5 [thin]=0 [cup]=0 [blocks]=0 [relief]=0)
for s in $scenes; do
  if [ ! -f "$work/scenes/$s/meta.json" ]; then
    "$bin" synth "$s" --out "$work/scenes/$s" --quiet | grep '^floor' | sed "s/^/$s /"
  fi
  for seed in $seeds; do
    out="$work/runs/$s-$preset-s$seed"
    [ -f "$out/metrics.json" ] || "$bin" reconstruct "$work/scenes/$s" --preset "$preset" \
      --seed "$seed" --quiet --out "$out" "$@" > "$out.log" 2>&1 || { echo "$s s$seed failed: $out.log"; continue; }
    python3 - "$out/metrics.json" "$s" "$seed" "${genus[$s]:-?}" <<'PY'
import json, sys
m = json.load(open(sys.argv[1])); c = m["chamfer"] or {}; me = m["mesh"]
f = lambda x: "n/a" if x is None else f"{x:.2f}"
print(f"{sys.argv[2]:13s} s{sys.argv[3]}  chamfer {c.get('chamfer_sum', float('nan')):.3f} mm  "
      f"genus {me.get('genus')} (truth {sys.argv[4]})  components {me.get('raw_components')} -> "
      f"{me['components']}  normal error {f(m.get('normal_error_deg'))} deg  "
      f"IoU {f(m.get('mask_iou_heldout'))}  {m['timings_s']['total']:.0f} s")
PY
  done
done
