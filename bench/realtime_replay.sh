#!/usr/bin/env bash
# bench/realtime_replay.sh [REC] [--out DIR]
#
# Is a replay, features included, faster than the video it replays (issue
# 13)? Replays REC twice, timed: with the defaults (SIFT on the full image)
# and with `features.max_feature_image_side: 640` (SIFT on the image halved,
# the patch fits still on the full one), and prints one JSON object per run
# and a table: the video's length (frames.csv's timestamps), keyframes and
# how many frames apart, the replay's wall time over the video's (below 1:
# faster than real time), points, peak memory and, when REC has its truth,
# the shares of points within 1/2/5 mm after a rigid fit.
#
# Without REC, renders the issue's walk into DIR/walk720 (once): `tagsfm
# synth box --frames 720`, a 24 s, 30 fps orbit at 1.5-3 m, 1280x720, noise
# 2, blur 0.7, where the keyframe rule takes a keyframe every ~9 frames.
#
# --out DIR   where the runs go (default: a new folder under /tmp)
# TAGSFM=path overrides the executable (default: build/tagsfm of this tree).
# Not run in CI (the render takes ~3 min and the replays ~1.5 min on 2 cores).
set -euo pipefail

here="$(cd "$(dirname "$0")/.." && pwd)"
tagsfm="${TAGSFM:-$here/build/tagsfm}"
rec=""
out=""
while [ $# -gt 0 ]; do
  case "$1" in
    --out) out="$2"; shift 2 ;;
    -h|--help) sed -n '2,19p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    -*) echo "realtime_replay.sh: unknown option $1" >&2; exit 2 ;;
    *) [ -z "$rec" ] || { echo "realtime_replay.sh: one recording only" >&2; exit 2; }; rec="$1"; shift ;;
  esac
done
[ -x "$tagsfm" ] || { echo "$tagsfm: not built (bash scripts/build.sh)" >&2; exit 1; }
[ -n "$out" ] || out="$(mktemp -d /tmp/realtime_replay.XXXXXX)"
mkdir -p "$out"
out="$(cd "$out" && pwd)"

if [ -z "$rec" ]; then
  rec="$out/walk720"
  if [ ! -f "$rec/frames.csv" ]; then
    rm -rf "$rec"
    echo "rendering the 720-frame walk into $rec ..." >&2
    "$tagsfm" synth box --out "$rec" --frames 720 --noise 2 --blur 0.7 > "$out/synth.log" 2>&1 \
      || { echo "synth failed: $(tail -3 "$out/synth.log")" >&2; exit 1; }
  fi
fi
[ -f "$rec/recording.yaml" ] || { echo "$rec/recording.yaml: missing" >&2; exit 1; }
rec="$(cd "$rec" && pwd)"

printf 'pipeline:\n  features:\n    max_feature_image_side: 640\n' > "$out/half.yaml"

run() {  # name, extra replay arguments...
  local name="$1"
  shift
  rm -rf "${out:?}/$name"
  local start end
  start=$(date +%s.%N)
  if ! "$tagsfm" replay "$rec" --out "$out/$name" "$@" > "$out/$name.log" 2>&1; then
    echo "{\"run\": \"$name\", \"error\": \"replay failed, see $out/$name.log\"}"
    return
  fi
  end=$(date +%s.%N)
  local summary=""
  if [ -d "$rec/ground_truth" ]; then
    summary="$("$tagsfm" evaluate "$out/$name" "$rec" --summary rigid 2> "$out/$name.evaluate.err" || true)"
  fi
  python3 - "$rec" "$out/$name" "$name" "$start" "$end" "$summary" <<'PY'
import csv, json, sys
rec, result, name, start, end, summary = sys.argv[1:7]
stamps = [int(r["timestamp_ns"]) for r in csv.DictReader(open(rec + "/frames.csv"))]
period = (stamps[-1] - stamps[0]) / max(1, len(stamps) - 1) if len(stamps) > 1 else 0
video_s = (stamps[-1] - stamps[0] + period) * 1e-9
report = json.load(open(result + "/report.json"))
wall = float(end) - float(start)
keyframes = report.get("feature_keyframes", 0)
row = {"run": name, "frames": len(stamps), "video_s": round(video_s, 2), "keyframes": keyframes,
       "frames_per_keyframe": round(len(stamps) / keyframes, 1) if keyframes else None,
       "replay_s": round(wall, 2), "realtime_ratio": round(wall / video_s, 3) if video_s > 0 else None,
       "points": report.get("feature_points"), "peak_rss_mb": round(report.get("peak_rss_mb", 0))}
if summary.strip():
    fields = summary.strip().split("\t")
    row["within_1_2_5_mm_pct"] = [float(f) for f in fields[4:7]]
print(json.dumps(row))
PY
}

{
  run full
  run half --config "$out/half.yaml"
} | tee "$out/realtime.jsonl"

python3 - "$out/realtime.jsonl" <<'PY'
import json, sys
rows = [json.loads(l) for l in open(sys.argv[1]) if l.strip()]
print()
print("| run | video | keyframes (every n frames) | replay | replay / video | points | within 1 / 2 / 5 mm | peak RSS |")
print("|---|---|---|---|---|---|---|---|")
for r in rows:
    if "error" in r:
        print("| %s | %s |" % (r["run"], r["error"]))
        continue
    w = r.get("within_1_2_5_mm_pct")
    print("| %s | %.1f s | %d (%s) | %.1f s | %.2f | %s | %s | %d MB |" % (
        {"full": "SIFT full size (default)", "half": "max_feature_image_side 640"}.get(r["run"], r["run"]),
        r["video_s"], r["keyframes"], r["frames_per_keyframe"], r["replay_s"], r["realtime_ratio"],
        f'{r["points"]:,}', " / ".join("%.1f" % x for x in w) + " %" if w else "n/a", r["peak_rss_mb"]))
PY
