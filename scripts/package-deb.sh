#!/usr/bin/env bash
# Builds the Debian package: the release binary, /etc/digiview/{digiview.toml,lens.cal}
# (configuration files dpkg keeps on upgrade), the systemd unit running DigiView as its own
# user, and the docs. Needs only dpkg-deb (every Debian has it).
#
#   scripts/package-deb.sh [--out DIR] [--no-build] [--binary PATH]
#
# --no-build packages target/release/digiview as it is (CI builds it once for the tests);
# --binary packages another build of it.
# Prints the .deb's path. Install it with: sudo apt install ./digiview_VERSION_ARCH.deb
set -euo pipefail
cd "$(dirname "$0")/.."

out=target/deb
build=1
binary=target/release/digiview
while (($#)); do
  case "$1" in
    --out) out=$2; shift 2 ;;
    --no-build) build=0; shift ;;
    --binary) binary=$2; build=0; shift 2 ;;
    *) echo "usage: $0 [--out DIR] [--no-build] [--binary PATH]" >&2; exit 2 ;;
  esac
done

if ((build)); then
  cargo build --release --locked --bin digiview >&2
fi
[ -x "$binary" ] || { echo "package-deb: $binary is missing: build it (cargo build --release)" >&2; exit 1; }

version=$(sed -n 's/^version = "\(.*\)"/\1/p' Cargo.toml | head -n 1)
arch=$(dpkg --print-architecture)
root=$(mktemp -d)
chmod 755 "$root"
trap 'rm -rf "$root"' EXIT

install -d "$root/DEBIAN" "$root/usr/bin" "$root/etc/digiview" "$root/lib/systemd/system" \
  "$root/usr/share/doc/digiview"
# Without its debug information: a tenth of the size.
strip --strip-debug -o "$root/usr/bin/digiview" "$binary"
chmod 755 "$root/usr/bin/digiview"
install -m 644 scripts/deb/digiview.toml "$root/etc/digiview/digiview.toml"
install -m 644 lens-cal/lens.cal "$root/etc/digiview/lens.cal"
install -m 644 scripts/deb/digiview.service "$root/lib/systemd/system/digiview.service"
install -m 644 README.md docs/*.md "$root/usr/share/doc/digiview/"
install -m 755 scripts/deb/postinst scripts/deb/prerm scripts/deb/postrm "$root/DEBIAN/"
printf '%s\n' /etc/digiview/digiview.toml /etc/digiview/lens.cal > "$root/DEBIAN/conffiles"
cat > "$root/usr/share/doc/digiview/copyright" <<COPYRIGHT
Format: https://www.debian.org/doc/packaging-manuals/copyright-format/1.0/
Upstream-Name: digiview
Files: *
License: MIT or Apache-2.0
COPYRIGHT
size=$(du -sk --exclude=DEBIAN "$root" | cut -f1)
cat > "$root/DEBIAN/control" <<CONTROL
Package: digiview
Version: $version
Architecture: $arch
Maintainer: DigiView developers <digiview@localhost>
Installed-Size: $size
Depends: libc6, libgcc-s1, adduser, libvulkan1, mesa-vulkan-drivers | vulkan-icd,
 libgstreamer1.0-0, libgstreamer-plugins-base1.0-0, libgstrtspserver-1.0-0,
 gstreamer1.0-plugins-base, gstreamer1.0-plugins-good, gstreamer1.0-plugins-bad,
 gstreamer1.0-plugins-ugly, gstreamer1.0-libav
Recommends: gstreamer1.0-rtsp, libegl1, libegl-mesa0, libgl1-mesa-dri
Section: video
Priority: optional
Description: onboard fisheye virtual-camera video head
 DigiView undistorts a fisheye camera's frames on the GPU into up to four steerable
 virtual cameras held steady against the vehicle's attitude, composes them, encodes
 H.264 and serves it over RTSP. It is steered over its binary protocol, over MAVLink
 (each view a camera and gimbal for ground stations) and over HTTP. The package runs
 it as the digiview service: configure /etc/digiview/digiview.toml, then check the
 machine with \`digiview doctor\`.
CONTROL

mkdir -p "$out"
deb="$out/digiview_${version}_${arch}.deb"
dpkg-deb --root-owner-group -Zxz --build "$root" "$deb" >&2
echo "$deb"
