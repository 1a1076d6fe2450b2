#!/bin/busybox sh
# Runs inside the vivid guest (see run_vivid.sh), with the host's root at
# /host: records from vivid's /dev/video0 with the host's tagsfm in each
# pixel format, then unplugs the camera (vivid's Disconnect control) in the
# middle of a recording. Everything lands in RESULTS for the host to check.
BUILD=$1
RESULTS=$2
R=/host$RESULTS
run() { chroot /host "$@"; }
FRAMES=${TAGSFM_VIVID_FRAMES:-45}

run v4l2-ctl -d /dev/video0 --all > "$R/v4l2-ctl-all.txt" 2>&1
run v4l2-ctl -d /dev/video0 --list-formats-ext > "$R/formats.txt" 2>&1
run v4l2-ctl -d /dev/video0 --list-ctrls > "$R/controls.txt" 2>&1

record() {  # NAME FORMAT BRIGHTNESS RECONNECT_WAIT_S [extra record arguments]
  name=$1 format=$2 brightness=$3 reconnect=$4
  shift 4
  cat > "$R/$name.yaml" <<EOF
capture:
  source: v4l2:/dev/video0
  width: 640
  height: 360
  fps: 30
  pixel_format: $format
  brightness: $brightness
  gain: 40
  exposure_us: 5000
  reconnect_wait_s: $reconnect
EOF
  start=$(date +%s)
  run "$BUILD/tagsfm" record --config "$RESULTS/$name.yaml" --out "$RESULTS/$name" --tag-size 0.05 "$@" \
    > "$R/$name.out" 2> "$R/$name.err"
  echo $? > "$R/$name.rc"
  echo $(( $(date +%s) - start )) > "$R/$name.seconds"
  run v4l2-ctl -d /dev/video0 -C brightness > "$R/$name.brightness" 2>&1
}

# At most 120 s: the recorder's start under TCG on a loaded host was seen to
# take over 20 s, the old limit, and the device was then unplugged before
# the recorder had opened it (the replug case then recorded without a gap).
wait_for_frames() {  # NAME COUNT: until the recording has COUNT frames (at most 120 s)
  i=0
  while [ $i -lt 600 ] && [ "$(ls "$R/$1/frames" 2>/dev/null | wc -l)" -lt "$2" ]; do sleep 0.2; i=$((i + 1)); done
}

record grey GREY 200 0 --frames "$FRAMES"
record yuyv YUYV 60 0 --frames "$FRAMES"

# libcamera's camera manager under this kernel: its UVC, vimc and simple
# pipeline handlers do not take vivid, so it must say there is no camera 0.
run env LIBCAMERA_LOG_LEVELS='*:ERROR' "$BUILD/tagsfm" record --source libcamera:0 --out "$RESULTS/libcamera" \
  --tag-size 0.05 --frames 5 > "$R/libcamera.out" 2> "$R/libcamera.err"
echo $? > "$R/libcamera.rc"

# Unplugged mid-capture: vivid's platform device unbound through sysfs, as
# the kernel removes a camera pulled from its USB port (the device node
# goes, open files get ENODEV). vivid's own Disconnect control was tried
# first and measured not to stop the stream: in 5 of 5 runs frames kept
# coming for 3 s after it (docs/capture.md). The recording so far stays,
# one line says so.
unplug() {
  echo "unbinding vivid.0 after $(ls "$R/$1/frames" | wc -l) frames" >> "$R/disconnect.txt"
  echo vivid.0 > /sys/bus/platform/drivers/vivid/unbind
}

# Unloads vivid as soon as nothing holds it open (at most 30 s), loads it again.
reload_vivid() {
  i=0
  until rmmod vivid 2>/dev/null; do
    i=$((i + 1))
    [ $i -ge 150 ] && { echo "vivid still in use after 30 s" >> "$R/disconnect.txt"; break; }
    sleep 0.2
  done
  echo "vivid unloaded after $i tries" >> "$R/disconnect.txt"
  insmod /modules/*-vivid.ko
}

# Capped at 300 frames so that a driver that never goes away cannot hang the test.
record unplug GREY 128 0 --frames 300 &
pid=$!
wait_for_frames unplug 10
unplug unplug
wait $pid

# Unplugged and plugged back (the driver reloaded) with capture.reconnect_wait_s:
# the recording goes on after the gap.
reload_vivid
for i in 1 2 3 4 5 6 7 8 9 10; do [ -e /dev/video0 ] && break; sleep 0.2; done
record replug GREY 128 60 --frames 40 &
pid=$!
wait_for_frames replug 10
unplug replug
# vivid unloads only once the recorder has closed the lost device (it
# notices within its frame timeout; under load that was seen to take
# longer than an immediate rmmod allowed, which left vivid loaded, unbound,
# and the camera never back).
reload_vivid
wait $pid
# Rendered frames with targets through the driver: vivid's HDMI output
# looped back into its HDMI input (loop_video; both at vivid's default
# 1280x720 timings, GREY on both sides, no text drawn over the picture),
# fed from loop_frames.raw (raw GREY frames the host test wrote) by
# v4l2-ctl, recorded by tagsfm from the capture node.
if [ -f "$R/loop_frames.raw" ]; then
  reload_vivid
  for i in 1 2 3 4 5 6 7 8 9 10; do [ -e /dev/video1 ] && break; sleep 0.2; done
  {
    run v4l2-ctl -d /dev/video0 --set-input=3
    run v4l2-ctl -d /dev/video1 --set-output=1
    run v4l2-ctl -d /dev/video0 -c loop_video=1 -c osd_text_mode=2
    run v4l2-ctl -d /dev/video1 --set-fmt-video-out=width=1280,height=720,pixelformat=GREY
    run v4l2-ctl -d /dev/video0 --get-input --get-fmt-video -C loop_video
    run v4l2-ctl -d /dev/video1 --get-output --get-fmt-video-out
  } > "$R/loop_setup.txt" 2>&1
  run v4l2-ctl -d /dev/video1 --stream-out-mmap --stream-from="$RESULTS/loop_frames.raw" --stream-loop \
    > "$R/loop_feed.txt" 2>&1 &
  feeder=$!
  sleep 1
  printf 'capture:\n  source: v4l2:/dev/video0\n  width: 1280\n  height: 720\n  pixel_format: GREY\n' > "$R/loop.yaml"
  run "$BUILD/tagsfm" record --config "$RESULTS/loop.yaml" --out "$RESULTS/loop" --tag-size 0.06 --frames 20 \
    > "$R/loop.out" 2> "$R/loop.err"
  echo $? > "$R/loop.rc"
  kill $feeder
fi
exit 0
