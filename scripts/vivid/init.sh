#!/bin/busybox sh
# /init of the vivid test guest (run_vivid.sh): loads the modules, mounts the
# host's root read-only at /host and the results share over the results
# folder's own path in it, runs guest.sh from the host's tree, powers off.
/bin/busybox --install -s /bin
export PATH=/bin
mount -t proc proc /proc
mount -t sysfs sys /sys
mount -t devtmpfs dev /dev
for ko in /modules/*.ko; do
  insmod "$ko" || echo "init: insmod $ko failed"
done
mount -t 9p -o trans=virtio,version=9p2000.L,ro host /host || echo "init: cannot mount the host"
mount -t 9p -o trans=virtio,version=9p2000.L,msize=262144 results /results || echo "init: cannot mount the results"
read -r BUILD RESULTS SCRIPTS < /results/guest_args
# The chroot sees the devices, a scratch /tmp and the results where the host has them.
mount --bind /dev /host/dev
mount -t proc proc /host/proc
mount -t sysfs sys /host/sys
# The scratch /tmp hides the host's: a build, scripts or results folder
# under the host's /tmp (a clone there) is bound back to its own path.
mkdir -p /hosttmp
mount --bind /host/tmp /hosttmp
mount -t tmpfs tmp /host/tmp
for dir in "$BUILD" "$SCRIPTS"; do
  case "$dir" in /tmp/*) mkdir -p "/host$dir" && mount --bind "/hosttmp/${dir#/tmp/}" "/host$dir" ;; esac
done
[ -d "/host$RESULTS" ] || mkdir -p "/host$RESULTS"
mount --bind /results "/host$RESULTS"
for i in 1 2 3 4 5 6 7 8 9 10; do [ -e /dev/video0 ] && break; sleep 0.2; done
sh "/host$SCRIPTS/guest.sh" "$BUILD" "$RESULTS" > /results/guest.log 2>&1
echo $? > /results/guest_rc
sync
umount "/host$RESULTS"
umount /results
poweroff -f
