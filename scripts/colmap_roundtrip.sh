#!/usr/bin/env bash
# Round trip through the real COLMAP:
#   1. synthesise a built-in scene (true cameras, ground truth);
#   2. run COLMAP on its images alone: CPU SIFT with one PINHOLE camera for all images (the
#      simulator's lens), the scene's masks as feature masks, exhaustive matching, the
#      incremental mapper; keep the model with the most registered images. Intrinsics:
#      `--intrinsics estimate` (default): COLMAP self-calibrates the focal lengths from its
#      default guess and keeps the principal point at the image centre, as for photographs of
#      unknown calibration; `--intrinsics known`: the scene's true K is given to COLMAP and held
#      fixed (a calibrated rig, as DTU's), so only the poses come from COLMAP;
#   3. convert that binary model to text and import both with `neus-aug import colmap` (masks
#      passed): the two scenes must be identical byte for byte. The region of interest (the
#      sphere NeuS reconstructs in) comes from `--roi-from auto` (default, the importer's: the
#      point nearest every optical axis when the cameras orbit the sparse points, with a radius
#      kept near the points; see `roi_auto` in src/import/mod.rs), `--roi-from points` (from the
#      sparse points, which here cover the side the cameras see, so the sphere leaves out part
#      of the side facing away from them; the summary says how much) or `--roi-from cameras` (the
#      point nearest every optical axis, the largest sphere every camera sees whole);
#   4. reconstruct the COLMAP-posed scene and the true-camera scene with the same preset, seed and
#      iterations;
#   5. map the COLMAP run's mesh (COLMAP's world frame: `reconstruct` maps it out of normalised
#      space with the imported scale_mat, and the importer adds no similarity) into the true frame
#      with the similarity between the two sets of camera centres, matched by image name
#      (Umeyama with scale: scripts/colmap_align.py, which checks itself first), and also with
#      the similarity fitted to the whole poses (centres and viewing directions; why: that
#      script's doc), and with the similarity between COLMAP's sparse points and the same tracks
#      triangulated with the true cameras (the "points" fit: it maps the structure the images
#      measured, and does not suffer the near-ambiguity of a distant camera's centre and
#      direction; that script's doc);
#   6. score the meshes with the same DTU Chamfer protocol (`neus-aug eval`) against the true
#      scene's ground truth and print: registered images, COLMAP's focal length, alignment
#      residual, the Chamfer sums and the ratio COLMAP / true against the acceptance bound 1.3
#      (judged on the alignment by the camera centres; the one by the whole poses printed beside).
#
#   scripts/colmap_roundtrip.sh WORKDIR [--scene NAME] [--preset P | --config FILE] [--seed S]
#                                       [--iterations N] [--intrinsics estimate|known]
#                                       [--roi-from auto|points|cameras] [--min-registered K]
#                                       [--bound B]
#                                       [--views N] [--resolution WxH] [--spp N] [--gt-spacing MM]
#   scripts/colmap_roundtrip.sh /tmp/rt                       # blob, fast preset, seed 0
#   scripts/colmap_roundtrip.sh /tmp/rt --iterations 800      # cheaper proof run
#   scripts/colmap_roundtrip.sh /tmp/rt --views 16 --spp 1 --gt-spacing 1 --config tiny.toml \
#       --intrinsics known                                    # the tiny version tests/ runs
#
# `--views`, `--resolution`, `--spp` and `--gt-spacing` are passed to `neus-aug synth`; `--config`
# replaces the preset with a configuration file for both reconstructions. Besides the printed
# summary, WORKDIR/summary<variant>.json holds the same figures (`tests/colmap_roundtrip.rs`
# reads it).
#
# WORKDIR keeps every step's output (true/, colmap[-known]/, scene_{bin,txt}[-known]-ROI/,
# runs/{true,colmap[-known]-ROI}/, logs/); a step whose output is already complete is not redone,
# so a rerun after a failure continues, and every variant shares the synthetic scene, the
# true-camera run, and (per intrinsics mode) the COLMAP model; a WORKDIR made with another scene,
# preset, seed or iteration count is refused. Exit
# status: 0 when the ratio (centres alignment) is within the bound, 1 when a step failed (the
# message says which and where its log is), 2 when every step worked but the ratio exceeds the
# bound.
# Needs COLMAP (installed with apt-get when missing and run as root), python3 (numpy is installed
# into target/py-venv by scripts/_pyenv.py), and the release binary (built when missing).
# Cost on 2 cores: COLMAP about 1.5 min for the 49 views of `blob`; each reconstruction what
# `reconstruct` costs (5-13 min at 1000 iterations of the fast preset with other jobs running).
set -euo pipefail

usage() {
  echo "usage: scripts/colmap_roundtrip.sh WORKDIR [--scene NAME] [--preset P | --config FILE]" \
    "[--seed S] [--iterations N] [--intrinsics estimate|known] [--roi-from auto|points|cameras]" \
    "[--min-registered K] [--bound B] [--views N] [--resolution WxH] [--spp N] [--gt-spacing MM]" \
    "(details: the comment at its top)" >&2
  exit 1
}
die() { echo "colmap_roundtrip: $*" >&2; exit 1; }

work=""
scene=blob
preset=fast
seed=0
iterations=""
min_registered=""
config=""
synth_args=()
bound=1.3
intrinsics=estimate
roi_from=auto
while [ $# -gt 0 ]; do
  case "$1" in
    --scene) scene=${2:?--scene needs a name}; shift 2 ;;
    --preset) preset=${2:?--preset needs a name}; shift 2 ;;
    --config) config=${2:?--config needs a file}; shift 2 ;;
    --views|--resolution|--spp|--gt-spacing)
      synth_args+=("$1" "${2:?$1 needs a value}"); shift 2 ;;
    --seed) seed=${2:?--seed needs a number}; shift 2 ;;
    --iterations) iterations=${2:?--iterations needs a number}; shift 2 ;;
    --min-registered) min_registered=${2:?--min-registered needs a number}; shift 2 ;;
    --bound) bound=${2:?--bound needs a number}; shift 2 ;;
    --intrinsics) intrinsics=${2:?--intrinsics needs estimate or known}; shift 2 ;;
    --roi-from) roi_from=${2:?--roi-from needs auto, cameras or points}; shift 2 ;;
    -h|--help) usage ;;
    -*) echo "unknown option $1" >&2; usage ;;
    *) [ -z "$work" ] || { echo "one WORKDIR only (got '$work' and '$1')" >&2; usage; }; work=$1; shift ;;
  esac
done
[ -n "$work" ] || usage
case "$intrinsics" in
  estimate) tag="" ;;
  known) tag="-known" ;;
  *) echo "--intrinsics is 'estimate' or 'known', not '$intrinsics'" >&2; usage ;;
esac
case "$roi_from" in
  auto|cameras|points) stag="$tag-$roi_from" ;;   # names of what depends on the region of interest
  *) echo "--roi-from is 'auto', 'cameras' or 'points', not '$roi_from'" >&2; usage ;;
esac
if [ -n "$config" ]; then
  [ -f "$config" ] || die "--config $config: no such file"
  config=$(cd "$(dirname "$config")" && pwd)/$(basename "$config")
  preset="config:$(sha256sum "$config" | cut -c1-16)"
fi
mkdir -p "$work/logs"
work=$(cd "$work" && pwd)
# Cached outputs are only valid for the parameters they were made with.
params="scene=$scene preset=$preset seed=$seed iterations=${iterations:-preset}"
[ ${#synth_args[@]} -eq 0 ] || params="$params synth=${synth_args[*]}"
if [ -f "$work/params" ]; then
  [ "$(cat "$work/params")" = "$params" ] \
    || die "$work was made with '$(cat "$work/params")', not '$params': use another WORKDIR"
else
  echo "$params" > "$work/params"
fi
here=$(cd "$(dirname "$0")/.." && pwd)
bin=${NEUS_AUG:-$here/target/release/neus-aug}
export QT_QPA_PLATFORM=offscreen   # COLMAP's Qt otherwise asks for a display
start_all=$SECONDS

# Runs "$@" with its output in logs/<name>.log; on failure prints the log's tail and stops.
step() {
  local name=$1; shift
  local log="$work/logs/$name.log" t0=$SECONDS
  echo "== $name" >&2
  if ! "$@" > "$log" 2>&1; then
    tail -n 15 "$log" >&2
    die "step '$name' failed (exit status above; full log: $log)"
  fi
  echo "   $name: $((SECONDS - t0)) s" >&2
}

# --- 0. tools ---------------------------------------------------------------------------------
if [ ! -x "$bin" ]; then
  step build bash -c "cd '$here' && cargo build --release --bin neus-aug"
fi
if ! command -v colmap > /dev/null; then
  if [ "$(id -u)" = 0 ] && command -v apt-get > /dev/null; then
    step install-colmap env DEBIAN_FRONTEND=noninteractive bash -c \
      "apt-get -o DPkg::Lock::Timeout=300 update && apt-get -o DPkg::Lock::Timeout=300 install -y colmap"
    command -v colmap > /dev/null || die "apt-get installed colmap but no 'colmap' is on PATH"
  else
    die "COLMAP is not installed and this is not root with apt-get: install it by hand (Debian/Ubuntu: \`sudo apt-get install colmap\`, or https://colmap.github.io/install.html), then rerun"
  fi
fi
command -v python3 > /dev/null || die "python3 is needed for the alignment step"
step align-self-check python3 "$here/scripts/colmap_align.py" --self-check
colmap help 2>&1 | sed -n '1p' >&2

# Reads a value from a JSON file: json FILE EXPR (EXPR in Python over `d`).
json() { python3 -c "import json,sys; d=json.load(open(sys.argv[1])); print($2)" "$1"; }

# --- 1. the true scene ---------------------------------------------------------------------------
true_scene="$work/true"
if [ ! -f "$true_scene/meta.json" ]; then
  rm -rf "$true_scene"
  step synth "$bin" synth "$scene" "${synth_args[@]}" --out "$true_scene" --quiet
  grep -E '^(wrote|floor)' "$work/logs/synth.log" >&2 || true
fi
scan=$(json "$true_scene/meta.json" 'd["scan"]')
n_views=$(find "$true_scene/image" -maxdepth 1 -name '*.png' | wc -l)
[ "$n_views" -gt 0 ] || die "no images in $true_scene/image"
min_registered=${min_registered:-$(( (n_views + 1) / 2 ))}

# --- 2. COLMAP on the images alone ------------------------------------------------------------
cm="$work/colmap$tag"
if [ ! -f "$cm/best/images.bin" ]; then
  rm -rf "$cm"; mkdir -p "$cm/sparse"
  mask_args=()
  if [ -d "$true_scene/mask" ]; then
    # COLMAP's mask for image NAME is <mask_path>/NAME.png; features only where it is non-zero.
    mkdir -p "$cm/masks"
    for img in "$true_scene"/image/*.png; do
      name=$(basename "$img"); num=$((10#${name%.png}))
      m=$(printf '%s/mask/%03d.png' "$true_scene" "$num")
      [ -f "$m" ] || die "no mask $m for image $name"
      cp "$m" "$cm/masks/$name.png"
    done
    mask_args=(--ImageReader.mask_path "$cm/masks")
  fi
  intr_args=() map_args=()
  if [ "$intrinsics" = known ]; then
    # The true K (one for every view; inspect's JSON has each camera's), held fixed by the mapper.
    k=$("$bin" inspect "$true_scene" --json - | python3 -c '
import json, sys
cams = json.load(sys.stdin)["cameras"]
k = cams[0]["k"]
same = all(abs(c["k"][i][j] - k[i][j]) <= 1e-9 * k[0][0] for c in cams for i in range(3) for j in range(3))
if not same or abs(k[0][1]) > 1e-9 * k[0][0]:
    sys.exit("the views do not share one skew-free K: no single PINHOLE camera")
print(",".join(repr(v) for v in (k[0][0], k[1][1], k[0][2], k[1][2])))') \
      || die "cannot read one shared K from $true_scene"
    intr_args=(--ImageReader.camera_params "$k")
    map_args=(--Mapper.ba_refine_focal_length 0 --Mapper.ba_refine_principal_point 0
      --Mapper.ba_refine_extra_params 0)
    echo "   known intrinsics fx,fy,cx,cy = $k" >&2
  fi
  step "colmap$tag-features" colmap feature_extractor --database_path "$cm/database.db" \
    --image_path "$true_scene/image" "${mask_args[@]}" \
    --ImageReader.camera_model PINHOLE --ImageReader.single_camera 1 "${intr_args[@]}" \
    --SiftExtraction.use_gpu 0
  step "colmap$tag-matching" colmap exhaustive_matcher --database_path "$cm/database.db" \
    --SiftMatching.use_gpu 0
  step "colmap$tag-mapper" colmap mapper --database_path "$cm/database.db" \
    --image_path "$true_scene/image" --output_path "$cm/sparse" "${map_args[@]}"
  # The model with the most registered images (images.bin starts with that count, u64 LE).
  best="" best_n=0
  for m in "$cm"/sparse/*/; do
    [ -f "$m/images.bin" ] || continue
    n=$(od -An -t u8 -N 8 "$m/images.bin" | tr -d ' ')
    echo "   model $(basename "$m"): $n registered images" >&2
    if [ "$n" -gt "$best_n" ]; then best=$m best_n=$n; fi
  done
  [ -n "$best" ] || die "COLMAP's mapper registered no model (see $work/logs/colmap$tag-mapper.log): too few matches between the $n_views images"
  cp -r "$best" "$cm/best.tmp" && mv "$cm/best.tmp" "$cm/best"
fi
registered=$(od -An -t u8 -N 8 "$cm/best/images.bin" | tr -d ' ')
[ "$registered" -ge "$min_registered" ] || die "COLMAP registered only $registered of $n_views images (at least $min_registered wanted; --min-registered changes it); see $work/logs/colmap$tag-mapper.log"
if [ ! -f "$cm/best_txt/images.txt" ]; then
  rm -rf "$cm/best_txt"; mkdir -p "$cm/best_txt"
  step "colmap$tag-to-text" colmap model_converter --input_path "$cm/best" \
    --output_path "$cm/best_txt" --output_type TXT
fi

# --- 3. import, binary and text ----------------------------------------------------------------
mask_flag=()
[ -d "$true_scene/mask" ] && mask_flag=(--masks "$true_scene/mask")
for form in bin txt; do
  model="$cm/best"; [ "$form" = txt ] && model="$cm/best_txt"
  out="$work/scene_$form$stag"
  if [ ! -f "$out/import.json" ]; then
    rm -rf "$out"
    step "import-$form$stag" "$bin" import colmap "$model" --images "$true_scene/image" \
      "${mask_flag[@]}" --roi-from "$roi_from" --out "$out"
  fi
done
sb="$work/scene_bin$stag"
for f in cameras_sphere.npz image mask; do
  [ -e "$sb/$f" ] || continue
  diff -r -q "$sb/$f" "$work/scene_txt$stag/$f" > /dev/null \
    || die "importing the binary and the text form of the same model gave different $f ($sb, $work/scene_txt$stag)"
done
echo "   binary and text models import to identical scenes" >&2
"$bin" inspect "$sb" > "$work/logs/inspect-colmap$stag.log" 2>&1 \
  || die "inspect of the imported scene failed: $work/logs/inspect-colmap$stag.log"
"$bin" inspect "$true_scene" > "$work/logs/inspect-true.log" 2>&1 \
  || die "inspect of the true scene failed: $work/logs/inspect-true.log"

# --- 4. reconstruct both -----------------------------------------------------------------------
rec_args=(--seed "$seed" --quiet)
if [ -n "$config" ]; then rec_args+=(--config "$config"); else rec_args+=(--preset "$preset"); fi
[ -n "$iterations" ] && rec_args+=(--iterations "$iterations")
for run in true "colmap$stag"; do
  src="$true_scene"; [ "$run" = true ] || src="$sb"
  out="$work/runs/$run"
  if [ ! -f "$out/metrics.json" ]; then
    mkdir -p "$work/runs"
    resume=(); [ -f "$out/config.toml" ] && resume=(--resume)
    step "reconstruct-$run" "$bin" reconstruct "$src" "${rec_args[@]}" "${resume[@]}" --out "$out"
  fi
  [ -s "$out/mesh.ply" ] || die "reconstruct wrote no mesh in $out"
done

# --- 5. align the COLMAP run's mesh into the true frame ----------------------------------------
step "align$stag" python3 "$here/scripts/colmap_align.py" --colmap-scene "$sb" \
  --true-scene "$true_scene" --mesh "$work/runs/colmap$stag/mesh.ply" \
  --out "$work/runs/colmap$stag/mesh_true_frame.ply" \
  --out-poses "$work/runs/colmap$stag/mesh_true_frame_poses.ply" \
  --colmap-model "$cm/best_txt" --out-points "$work/runs/colmap$stag/mesh_true_frame_points.ply" \
  --json "$work/align$stag.json"

# --- 6. score both with the same protocol ------------------------------------------------------
step eval-true "$bin" eval --mesh "$work/runs/true/mesh.ply" --scan "$scan" \
  --gt-root "$true_scene" --seed "$seed" --json "$work/eval_true.json"
step "eval-colmap$stag" "$bin" eval --mesh "$work/runs/colmap$stag/mesh_true_frame.ply" \
  --scan "$scan" --gt-root "$true_scene" --seed "$seed" --json "$work/eval_colmap$stag.json"
step "eval-colmap$stag-poses" "$bin" eval \
  --mesh "$work/runs/colmap$stag/mesh_true_frame_poses.ply" --scan "$scan" \
  --gt-root "$true_scene" --seed "$seed" --json "$work/eval_colmap$stag-poses.json"
step "eval-colmap$stag-points" "$bin" eval \
  --mesh "$work/runs/colmap$stag/mesh_true_frame_points.ply" --scan "$scan" \
  --gt-root "$true_scene" --seed "$seed" --json "$work/eval_colmap$stag-points.json"

c_true=$(json "$work/eval_true.json" 'd["chamfer_sum"]')
c_colmap=$(json "$work/eval_colmap$stag.json" 'd["chamfer_sum"]')
fx() { "$bin" inspect "$1" --json - | python3 -c 'import json,sys; d=json.load(sys.stdin); print(d["fx"][0])'; }
python3 - "$work" "$scene" "$preset" "$seed" "${iterations:-preset}" "$registered" "$n_views" \
  "$c_true" "$c_colmap" "$bound" "$((SECONDS - start_all))" "$stag" "$intrinsics" "$roi_from" \
  "$(fx "$sb")" "$(fx "$true_scene")" <<'PY'
import json, sys
work, scene, preset, seed, iters, reg, n, ct, cc, bound, wall, stag, intr, roi, fxc, fxt = sys.argv[1:]
a = json.load(open(f"{work}/align{stag}.json"))
et, ec, ep, eq = (json.load(open(f"{work}/eval_{k}.json"))
                  for k in ("true", f"colmap{stag}", f"colmap{stag}-poses", f"colmap{stag}-points"))
ct, cc, bound = float(ct), float(cc), float(bound)
ratio, cp, cq = cc / ct, ep["chamfer_sum"], eq["chamfer_sum"]
print(f"COLMAP round trip: scene {scene}, preset {preset}, seed {seed}, iterations {iters}, "
      f"intrinsics {intr}, region of interest from {roi}")
print(f"registered images      {reg} of {n}")
print(f"focal length fx        COLMAP {float(fxc):.2f} px, true {float(fxt):.2f} px "
      f"({100 * (float(fxc) / float(fxt) - 1):+.1f} %)")
print(f"alignment residual     rms {a['residual_rms']:.3f} mm, max {a['residual_max']:.3f} mm "
      f"(camera centres, Umeyama scale {a['scale']:.4g}); poses fit: viewing directions "
      f"{a['poses']['axis_angle_rms_deg']:.3f} deg rms, its rotation "
      f"{a['poses']['rotation_from_centres_fit_deg']:.3f} deg from the centres fit's")
if "gt_outside_roi" in a:
    print(f"true surface outside   {100 * a['gt_outside_roi']:.1f} % (of gt_mesh.ply, outside the "
          "imported region of interest)")
print(f"Chamfer, true cameras  {ct:.3f} mm (accuracy {et['mean_d2s']:.3f}, completeness {et['mean_s2d']:.3f})")
print(f"Chamfer, COLMAP        {cc:.3f} mm (accuracy {ec['mean_d2s']:.3f}, completeness {ec['mean_s2d']:.3f}; "
      "mesh aligned by the camera centres)")
print(f"ratio COLMAP / true    {ratio:.3f} (bound {bound}: {'within' if ratio <= bound else 'EXCEEDED'})")
print(f"  aligned by the poses {cp:.3f} mm (accuracy {ep['mean_d2s']:.3f}, completeness "
      f"{ep['mean_s2d']:.3f}), ratio {cp / ct:.3f}")
print(f"  aligned by the points {cq:.3f} mm (accuracy {eq['mean_d2s']:.3f}, completeness "
      f"{eq['mean_s2d']:.3f}), ratio {cq / ct:.3f}; sparse points fit residual median "
      f"{a['points']['residual_median']:.3f} mm")
print(f"wall time              {wall} s (this invocation)")
summary = {
    "scene": scene, "preset": preset, "seed": int(seed), "iterations": iters,
    "intrinsics": intr, "roi_from": roi, "registered": int(reg), "views": int(n),
    "fx_colmap": float(fxc), "fx_true": float(fxt),
    "centre_residual_rms_mm": a["residual_rms"], "centre_residual_max_mm": a["residual_max"],
    "gt_outside_roi": a.get("gt_outside_roi"),
    "chamfer_true_mm": ct, "chamfer_colmap_mm": cc, "chamfer_colmap_poses_mm": cp,
    "chamfer_colmap_points_mm": cq, "points_residual_median_mm": a["points"]["residual_median"],
    "ratio": ratio, "ratio_poses": cp / ct, "ratio_points": cq / ct, "bound": bound, "within_bound": ratio <= bound,
    "wall_s": int(wall),
}
with open(f"{work}/summary{stag}.json", "w") as f:
    json.dump(summary, f, indent=2)
sys.exit(0 if ratio <= bound else 2)
PY
