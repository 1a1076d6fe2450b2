#!/usr/bin/env bash
# Runs tagsfm's capture against the kernel's own virtual camera driver
# (vivid), in a throw-away qemu guest: Debian's kernel package, a busybox
# initramfs that loads vivid and 9p, the host's root shared read-only and
# RESULTS shared writable. The guest runs scripts/vivid/guest.sh, which
# records from /dev/video0 with the host's build/tagsfm; the caller checks
# RESULTS (tests/capture/vivid_capture_test.cpp).
#
#   scripts/vivid/run_vivid.sh BUILD_DIR RESULTS_DIR
#
# Exit 0: the guest ran (its own results are in RESULTS); 77: something
# needed is missing (qemu, busybox-static, the kernel package), said on the
# last line; anything else: the guest did not run.
set -euo pipefail

BUILD=$(realpath "$1")
RESULTS=$(realpath "$2")
HERE=$(dirname "$(realpath "$0")")
CACHE="$BUILD/vivid"
skip() { echo "vivid: skipped: $*"; exit 77; }

command -v qemu-system-x86_64 >/dev/null || skip "qemu-system-x86_64 is not installed (apt-get install qemu-system-x86)"
BUSYBOX=/bin/busybox  # busybox-static's; a dynamic one would need its libraries in the initramfs
{ [ -x "$BUSYBOX" ] && ! ldd "$BUSYBOX" >/dev/null 2>&1; } || skip "a static busybox is needed (apt-get install busybox-static)"
command -v cpio >/dev/null || skip "cpio is not installed"
command -v depmod >/dev/null || skip "depmod is not installed (apt-get install kmod)"
[ -x "$BUILD/tagsfm" ] || skip "$BUILD/tagsfm is not built"

# Debian's kernel, downloaded once and kept in the build folder.
mkdir -p "$CACHE/cache"
DEB=$(ls "$CACHE"/cache/linux-image-6.1.0-*-amd64_*.deb 2>/dev/null | sort -V | tail -1 || true)
if [ -z "$DEB" ]; then
  PKG=$(apt-cache search --names-only '^linux-image-6\.1\.0-[0-9]+-amd64$' 2>/dev/null | awk '{print $1}' | sort -V | tail -1)
  [ -n "$PKG" ] || skip "no linux-image-6.1.0-*-amd64 package is known to apt (apt-get update?)"
  (cd "$CACHE/cache" && apt-get download "$PKG" >/dev/null 2>&1) || skip "apt-get download $PKG failed (offline?)"
  DEB=$(ls "$CACHE"/cache/linux-image-6.1.0-*-amd64_*.deb | sort -V | tail -1)
fi
KROOT="$CACHE/kernel"
if [ ! -f "$KROOT/done" ] || [ "$(cat "$KROOT/done")" != "$DEB" ]; then
  rm -rf "$KROOT" && mkdir -p "$KROOT"
  dpkg-deb -x "$DEB" "$KROOT"
  echo "$DEB" > "$KROOT/done"
fi
KVER=$(ls "$KROOT/lib/modules" | head -1)
VMLINUZ="$KROOT/boot/vmlinuz-$KVER"

# The initramfs: busybox, the modules in load order, and init.
INITRD="$CACHE/initramfs-$KVER.cpio.gz"
if [ ! -f "$INITRD" ] || [ "$HERE/init.sh" -nt "$INITRD" ]; then
  depmod -b "$KROOT" "$KVER"
  ROOT="$CACHE/initramfs"
  rm -rf "$ROOT" && mkdir -p "$ROOT"/{bin,dev,proc,sys,host,results,modules}
  cp "$BUSYBOX" "$ROOT/bin/busybox"
  for m in vivid 9p 9pnet_virtio virtio_pci; do
    modprobe -d "$KROOT" -S "$KVER" --show-depends "$m" | awk '$1 == "insmod" {print $2}'
  done | awk '!seen[$0]++' > "$CACHE/modules.order"
  i=0
  while read -r ko; do
    cp "$ko" "$ROOT/modules/$(printf '%02d' $i)-$(basename "$ko")"
    i=$((i + 1))
  done < "$CACHE/modules.order"
  cp "$HERE/init.sh" "$ROOT/init"
  chmod +x "$ROOT/init"
  (cd "$ROOT" && find . | cpio -o -H newc --quiet | gzip -1) > "$INITRD"
fi

# The guest script's path on the host is its path in the guest under /host.
mkdir -p "$RESULTS"
rm -f "$RESULTS/guest_rc"
echo "$(realpath "$BUILD") $RESULTS $HERE" > "$RESULTS/guest_args"
timeout 900 qemu-system-x86_64 -accel tcg -m 1024 -smp 1 -nographic -no-reboot \
  -kernel "$VMLINUZ" -initrd "$INITRD" \
  -append "console=ttyS0 quiet panic=-1 no_timer_check tagsfm_results=$RESULTS" \
  -nic none -virtfs local,path=/,mount_tag=host,security_model=none,readonly=on,multidevs=remap \
  -virtfs local,path="$RESULTS",mount_tag=results,security_model=none \
  > "$RESULTS/console.log" 2>&1 || true
[ -f "$RESULTS/guest_rc" ] || { echo "vivid: the guest did not finish (see $RESULTS/console.log)"; tail -20 "$RESULTS/console.log"; exit 1; }
echo "vivid: guest finished with $(cat "$RESULTS/guest_rc")"
