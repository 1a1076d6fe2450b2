#!/usr/bin/env bash
# Installs the tagsfm daemon as a systemd service that starts at boot:
#   sudo bash scripts/install-service.sh CONFIG.yaml
# copies build/tagsfm to /usr/local/bin, CONFIG to /etc/tagsfm/run.yaml (after
# `tagsfm run --check-config`), scripts/tagsfm.service to
# /etc/systemd/system/, then enables and starts it. Run again to update.
# --no-start installs and enables without starting (e.g. in an image build).
set -euo pipefail

usage() { sed -n '2,7p' "$0" | sed 's/^# \{0,1\}//'; }
start=1
config=""
for arg in "$@"; do
  case "$arg" in
    -h|--help) usage; exit 0 ;;
    --no-start) start=0 ;;
    *) config="$arg" ;;
  esac
done
if [ -z "$config" ]; then usage >&2; exit 2; fi
here="$(cd "$(dirname "$0")/.." && pwd)"
exe="$here/build/tagsfm"
if [ ! -x "$exe" ]; then echo "install-service: $exe not found: build first (bash scripts/build.sh)" >&2; exit 1; fi
if [ "$(id -u)" -ne 0 ]; then echo "install-service: run as root (sudo)" >&2; exit 1; fi
if ! command -v systemctl > /dev/null; then echo "install-service: systemctl not found: this machine does not run systemd" >&2; exit 1; fi

# A config with errors would only restart-loop: refuse it here, naming every field.
"$exe" run --check-config "$config"

install -D -m 0755 "$exe" /usr/local/bin/tagsfm
install -D -m 0644 "$config" /etc/tagsfm/run.yaml
install -D -m 0644 "$here/firmware_config/README.md" /usr/local/share/doc/tagsfm/firmware_config/README.md
install -D -m 0644 "$here/scripts/tagsfm.service" /etc/systemd/system/tagsfm.service
mkdir -p /var/lib/tagsfm/captures
systemctl daemon-reload
systemctl enable tagsfm.service
if [ "$start" -eq 1 ]; then
  systemctl restart tagsfm.service
  systemctl --no-pager status tagsfm.service | head -5 || true
fi
echo "install-service: installed; logs: journalctl -u tagsfm -f"
