#!/usr/bin/env bash
# bench/compare_colmap.sh REC [--out DIR] [--reuse]
#
# tagsfm side by side with COLMAP 3.8 on one recording with ground truth
# (issue 13): COLMAP (Debian's colmap, CPU only, the intrinsics of
# recording.yaml held fixed), `tagsfm replay REC` (targets + features) and
# `tagsfm replay REC --no-targets` (feature SfM alone), each timed and scored
# by `tagsfm evaluate`, in one table, and the ratios of tagsfm's points and
# wall time to COLMAP's under it. tagsfm with targets is scored in its
# own metric frame: as it is when REC names a target map, else after a rigid
# fit (no scale) of its target corners; COLMAP and --no-targets after a
# similarity alignment of their camera centres to the true ones.
#
# --out DIR   where the runs go (default: a new folder under /tmp)
# --reuse     keep the runs already in DIR (their recorded wall times) and
#             only redo what is missing: for re-rendering the table.
# TAGSFM=path overrides the executable (default: build/tagsfm of this tree).
# Not run in CI (COLMAP takes minutes); the scoring side is tested by
# EvaluateColmapModel.* in tests/eval/.
set -euo pipefail

here="$(cd "$(dirname "$0")/.." && pwd)"
tagsfm="${TAGSFM:-$here/build/tagsfm}"
rec=""
out=""
reuse=0
while [ $# -gt 0 ]; do
  case "$1" in
    --out) out="$2"; shift 2 ;;
    --reuse) reuse=1; shift ;;
    -h|--help) sed -n '2,18p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    -*) echo "compare_colmap.sh: unknown option $1" >&2; exit 2 ;;
    *) [ -z "$rec" ] || { echo "compare_colmap.sh: one recording only" >&2; exit 2; }; rec="$1"; shift ;;
  esac
done
[ -n "$rec" ] || { echo "usage: bench/compare_colmap.sh REC [--out DIR] [--reuse]" >&2; exit 2; }
[ -d "$rec" ] || { echo "$rec: not a recording directory" >&2; exit 1; }
rec="$(cd "$rec" && pwd)"
[ -f "$rec/recording.yaml" ] || { echo "$rec/recording.yaml: missing" >&2; exit 1; }
[ -d "$rec/ground_truth" ] || { echo "$rec/ground_truth: missing; the comparison needs the truth" >&2; exit 1; }
[ -x "$tagsfm" ] || { echo "$tagsfm: not built (bash scripts/build.sh)" >&2; exit 1; }
command -v colmap > /dev/null || { echo "colmap: not installed (apt-get install colmap)" >&2; exit 1; }
[ -n "$out" ] || out="$(mktemp -d /tmp/compare_colmap.XXXXXX)"
mkdir -p "$out"
out="$(cd "$out" && pwd)"

now() { date +%s.%N; }
elapsed() { awk -v a="$1" -v b="$2" 'BEGIN { printf "%.1f", b - a }'; }

# --- The camera block of recording.yaml as COLMAP's model and parameters.
# COLMAP's pixel centres are at +0.5 (the image's corner is 0,0), OpenCV's
# and ours at 0: the principal point moves by half a pixel.
yaml_value() {  # block, key: a scalar of recording.yaml's top-level block
  awk -v block="$1:" -v key="$2:" '
    /^[^ #]/ { in_block = ($1 == block) }
    in_block && $1 == key { sub(/^[^:]*:[ ]*/, ""); sub(/[ ]*#.*/, ""); print; exit }' "$rec/recording.yaml"
}
camera_value() { yaml_value camera "$1"; }
fx="$(camera_value fx)"; fy="$(camera_value fy)"; cx="$(camera_value cx)"; cy="$(camera_value cy)"
lens="$(camera_value model)"
distortion="$(camera_value distortion | tr -d '[] ' )"
[ -n "$fx" ] && [ -n "$fy" ] && [ -n "$cx" ] && [ -n "$cy" ] || {
  echo "$rec/recording.yaml: camera.fx/fy/cx/cy missing; COLMAP is run with the intrinsics fixed (tagsfm calibrate first)" >&2
  exit 1
}
cx_c="$(awk -v v="$cx" 'BEGIN { printf "%.10g", v + 0.5 }')"
cy_c="$(awk -v v="$cy" 'BEGIN { printf "%.10g", v + 0.5 }')"
IFS=, read -r -a d <<< "${distortion:-}"
all_zero=1
for v in "${d[@]:-}"; do
  if [ -n "$v" ] && awk -v v="$v" 'BEGIN { exit !(v + 0 != 0) }'; then all_zero=0; fi
done
coef() { local v="${d[$1]:-0}"; echo "${v:-0}"; }
if [ "$lens" = "fisheye" ]; then
  model=OPENCV_FISHEYE; params="$fx,$fy,$cx_c,$cy_c,$(coef 0),$(coef 1),$(coef 2),$(coef 3)"
elif [ "$all_zero" = 1 ]; then
  model=PINHOLE; params="$fx,$fy,$cx_c,$cy_c"
elif [ "${#d[@]}" -le 5 ] && awk -v v="$(coef 4)" 'BEGIN { exit !(v + 0 == 0) }'; then
  model=OPENCV; params="$fx,$fy,$cx_c,$cy_c,$(coef 0),$(coef 1),$(coef 2),$(coef 3)"
elif [ "${#d[@]}" -le 8 ]; then
  model=FULL_OPENCV
  params="$fx,$fy,$cx_c,$cy_c,$(coef 0),$(coef 1),$(coef 2),$(coef 3),$(coef 4),$(coef 5),$(coef 6),$(coef 7)"
else
  echo "$rec/recording.yaml: ${#d[@]} distortion coefficients (thin prism / tilt) have no COLMAP model" >&2
  exit 1
fi

# --- COLMAP: the image files frames.csv names, relative to REC.
colmap_dir="$out/colmap"
if [ "$reuse" = 0 ] || [ ! -f "$colmap_dir/wall_s" ]; then
  rm -rf "$colmap_dir"
  mkdir -p "$colmap_dir/sparse"
  awk -F, 'NR == 1 { for (i = 1; i <= NF; ++i) if ($i == "file") col = i; next }
           col && $col != "" { print $col }' "$rec/frames.csv" > "$colmap_dir/images.list"
  [ -s "$colmap_dir/images.list" ] || { echo "$rec/frames.csv: no file column or no rows" >&2; exit 1; }
  if grep -q '^/' "$colmap_dir/images.list"; then
    echo "$rec/frames.csv: absolute image paths; COLMAP needs them below REC" >&2; exit 1
  fi
  echo "COLMAP: $(wc -l < "$colmap_dir/images.list") images, $model $params (fixed)" >&2
  start="$(now)"
  {
    colmap feature_extractor --database_path "$colmap_dir/database.db" --image_path "$rec" \
      --image_list_path "$colmap_dir/images.list" --ImageReader.single_camera 1 \
      --ImageReader.camera_model "$model" --ImageReader.camera_params "$params" --SiftExtraction.use_gpu 0
    colmap exhaustive_matcher --database_path "$colmap_dir/database.db" --SiftMatching.use_gpu 0
    colmap mapper --database_path "$colmap_dir/database.db" --image_path "$rec" \
      --output_path "$colmap_dir/sparse" --Mapper.ba_refine_focal_length 0 \
      --Mapper.ba_refine_principal_point 0 --Mapper.ba_refine_extra_params 0
  } > "$colmap_dir/colmap.log" 2>&1 || { echo "COLMAP failed; see $colmap_dir/colmap.log" >&2; exit 1; }
  # The largest model (most registered images) as text.
  best=""; best_images=-1
  for model_dir in "$colmap_dir"/sparse/*/; do
    [ -d "$model_dir" ] || continue
    txt="$colmap_dir/txt_$(basename "$model_dir")"
    mkdir -p "$txt"
    colmap model_converter --input_path "$model_dir" --output_path "$txt" --output_type TXT >> "$colmap_dir/colmap.log" 2>&1
    n="$(grep -v '^#' "$txt/images.txt" | awk 'NR % 2 == 1 && NF >= 10' | wc -l)"
    if [ "$n" -gt "$best_images" ]; then best="$txt"; best_images="$n"; fi
  done
  end="$(now)"
  [ -n "$best" ] || { echo "COLMAP made no model; see $colmap_dir/colmap.log" >&2; exit 1; }
  rm -rf "$colmap_dir/model"
  mv "$best" "$colmap_dir/model"
  elapsed "$start" "$end" > "$colmap_dir/wall_s"
fi

# --- tagsfm, with and without targets.
run_tagsfm() {  # name, extra replay arguments...
  local dir="$out/$1"; shift
  if [ "$reuse" = 1 ] && [ -f "$dir/wall_s" ]; then return; fi
  rm -rf "$dir"
  mkdir -p "$dir"
  local start end
  start="$(now)"
  if "$tagsfm" replay "$rec" --out "$dir/result" "$@" > "$dir/replay.log" 2>&1; then
    end="$(now)"
    elapsed "$start" "$end" > "$dir/wall_s"
  else
    # Not available yet (or failed): the row says so, with the command's words.
    tail -n 1 "$dir/replay.log" | sed 's/^.*\] //; s/^error: //' > "$dir/unavailable"
    echo "n/a" > "$dir/wall_s"
  fi
}
run_tagsfm hybrid
run_tagsfm no_targets --no-targets

# --- One table. `tagsfm evaluate --summary VARIANT` prints tab-separated:
# registered, ground-truth frames, points, mean reprojection error (px),
# shares within 1/2/5 mm (%), the similarity fit's scale error (ppm).
row() {  # label, result dir, variant, scale column text ("" = the fit's)
  local label="$1" dir="$2" variant="$3" scale_text="$4" wall="$5" summary
  if ! summary="$("$tagsfm" evaluate "$dir" "$rec" --summary "$variant" 2> "$out/evaluate.err")"; then
    printf '| %-22s | %s |\n' "$label" "evaluate failed: $(head -c 200 "$out/evaluate.err")"
    return
  fi
  IFS=$'\t' read -r registered truth points reprojection w1 w2 w5 scale_ppm <<< "$summary"
  row_points="$points"
  [ -n "$scale_text" ] || scale_text="$scale_ppm ppm"
  printf '| %-22s | %-10s | %9s | %8s px | %5s %% | %5s %% | %5s %% | %-22s | %7s s |\n' "$label" "$registered/$truth" \
    "$points" "$reprojection" "$w1" "$w2" "$w5" "$scale_text" "$wall"
}

echo
echo "Recording: $rec ($(wc -l < "$colmap_dir/images.list") frames); runs in $out"
printf '| %-22s | %-10s | %9s | %11s | %7s | %7s | %7s | %-22s | %9s |\n' "" "registered" "points" "reproj." "<= 1 mm" \
  "<= 2 mm" "<= 5 mm" "scale error" "wall time"
printf '|%s|%s|%s|%s|%s|%s|%s|%s|%s|\n' "------------------------" "------------" "-----------" "-------------" \
  "---------" "---------" "---------" "------------------------" "-----------"
# tagsfm's frame is the truth's when REC names a target map; without one it
# is its own (the first tag's), and a rigid fit, which keeps its metric
# scale, puts it into the true frame.
row_points=""
if [ -n "$(yaml_value targets map)" ]; then
  row "tagsfm (targets)" "$out/hybrid/result" as_is "" "$(cat "$out/hybrid/wall_s")"
else
  row "tagsfm (targets) +" "$out/hybrid/result" rigid "" "$(cat "$out/hybrid/wall_s")"
fi
hybrid_points="$row_points"
if [ -f "$out/no_targets/unavailable" ]; then
  printf '| %-22s | n/a: %s |\n' "tagsfm --no-targets" "$(cat "$out/no_targets/unavailable")"
else
  row "tagsfm --no-targets *" "$out/no_targets/result" similarity "scaled by the fit" "$(cat "$out/no_targets/wall_s")"
fi
row_points=""
row "COLMAP 3.8 *" "$colmap_dir/model" similarity "scaled by the fit" "$(cat "$colmap_dir/wall_s")"
colmap_points="$row_points"
[ -n "$(yaml_value targets map)" ] || echo "+ after a rigid alignment (no target map: tagsfm's world is its first tag's; the fit keeps its scale)."
echo "* after a similarity alignment of the camera centres to the true ones (no metric scale of its own)."
echo "Points: tagsfm's feature points (features.csv; target corners apart), COLMAP's points3D.txt."
echo "Reprojection: mean over points of each point's stored error: tagsfm's per-point RMS, COLMAP's per-point mean (RMS >= mean)."
echo "Scale error of tagsfm (targets): scale - 1 of the similarity fit of its target corners to the true ones."
# The issue's targets are ratios against COLMAP from one run: say them.
hybrid_wall="$(cat "$out/hybrid/wall_s")" colmap_wall="$(cat "$colmap_dir/wall_s")"
if [[ "$hybrid_points" =~ ^[0-9]+$ && "$colmap_points" =~ ^[0-9]+$ && "$colmap_points" -gt 0 &&
      "$hybrid_wall" =~ ^[0-9.]+$ && "$colmap_wall" =~ ^[0-9.]+$ ]]; then
  awk -v p="$hybrid_points" -v cp="$colmap_points" -v w="$hybrid_wall" -v cw="$colmap_wall" \
    'BEGIN { if (w > 0) printf "tagsfm (targets) against COLMAP 3.8, this run: %.2fx the points, %.1fx less wall time.\n", p / cp, cw / w }'
fi
