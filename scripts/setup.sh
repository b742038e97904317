#!/usr/bin/env bash
# Installs the system packages DigiView needs that this Debian machine lacks (as root, or
# through sudo), and checks the Rust toolchain. Safe to run again: it installs only what is
# missing.
set -euo pipefail

packages=(
  build-essential pkg-config
  # Vulkan and Mesa's lavapipe software driver: the GPU path runs on it where no GPU is.
  libvulkan1 mesa-vulkan-drivers vulkan-tools
  # EGL and Mesa's GL drivers (llvmpipe where no GPU is): the GL backend (--backend gl), the
  # fallback where Vulkan is missing or draws wrong.
  libegl1 libegl-mesa0 libgl1-mesa-dri
  # GStreamer: decoding, H.264 encoding and the RTSP server.
  libgstreamer1.0-dev libgstreamer-plugins-base1.0-dev libgstrtspserver-1.0-dev
  gstreamer1.0-plugins-base gstreamer1.0-plugins-good gstreamer1.0-plugins-bad
  gstreamer1.0-plugins-ugly gstreamer1.0-libav gstreamer1.0-tools
  # rtspclientsink: publishing the stream to a relay (serve --publish rtsp://...).
  gstreamer1.0-rtsp
  # systemd-analyze: the package's unit file is verified in the tests.
  systemd
  # ffprobe and ffplay: a second RTSP client in the tests, and FFmpeg's v360 for comparison.
  ffmpeg
  # exiftool: reads the stills' EXIF and XMP in the tests, as mapping pipelines check them.
  libimage-exiftool-perl
  # libfaketime: the clock-step test sets the system clock an hour forward and back for
  # DigiView's process alone.
  faketime
  # Chromium driven over WebDriver: the tuning page's end-to-end tests.
  chromium chromium-driver
  # pip fetches the onnxruntime wheel, whose ONNX Runtime library the ONNX detector loads;
  # venv holds the MAVLink peers the tests drive DigiView with (below).
  python3 python3-pip python3-venv
)

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done

# On Debian 12 (bookworm), lavapipe comes from bookworm-backports: Mesa 25 rather than 22.3,
# whose mip-chain passes take about a third longer (docs/performance.md, "Mesa 22.3"). Mesa's
# GL drivers come from there with it, so both backends share one Mesa.
mesa_packages=(mesa-vulkan-drivers libegl-mesa0 libgl1-mesa-dri)
backports=()
if [ -r /etc/os-release ] && [ "$(. /etc/os-release; echo "${VERSION_CODENAME:-}")" = bookworm ]; then
  for p in "${mesa_packages[@]}"; do
    mesa=$(dpkg-query -W -f='${Version}' "$p" 2>/dev/null || true)
    if [ -z "$mesa" ] || dpkg --compare-versions "$mesa" lt 25; then
      backports=("${mesa_packages[@]}")
    fi
  done
  for i in "${!missing[@]}"; do
    for p in "${backports[@]}"; do
      [ "${missing[$i]:-}" = "$p" ] && unset "missing[$i]"
    done
  done
fi

as_root=()
if ((${#missing[@]} + ${#backports[@]})) && [ "$(id -u)" != 0 ]; then
  command -v sudo >/dev/null || { echo "setup: run as root (or install sudo) to install: ${missing[*]} ${backports[*]}" >&2; exit 1; }
  as_root=(sudo)
fi
# The archive this machine's apt already takes Debian 12 from (one-line sources or deb822),
# of which bookworm-backports is another suite; empty where none is configured.
bookworm_archive() {
  grep -hsE '^[[:space:]]*deb[[:space:]]' /etc/apt/sources.list /etc/apt/sources.list.d/*.list |
    sed -E 's/\[[^]]*\]//' | awk '$3 == "bookworm" { print $2; exit }'
  awk 'BEGIN { RS = ""; FS = "\n" }
    {
      uris = ""; suites = ""
      for (i = 1; i <= NF; i++) {
        if ($i ~ /^URIs:/) { uris = $i; sub(/^URIs:[ \t]*/, "", uris) }
        if ($i ~ /^Suites:/) { suites = " " $i " "; sub(/^ Suites:/, " ", suites) }
      }
      if (uris != "" && suites ~ /[ \t]bookworm[ \t]/) { split(uris, u, " "); print u[1]; exit }
    }' /etc/apt/sources.list.d/*.sources 2>/dev/null
}
if ((${#backports[@]})) && ! grep -rqs '^[^#]*bookworm-backports' /etc/apt/sources.list /etc/apt/sources.list.d; then
  archive=$(bookworm_archive | head -n 1)
  if [ -n "$archive" ]; then
    echo "setup: adding bookworm-backports of $archive to apt's sources"
    echo "deb $archive bookworm-backports main" |
      "${as_root[@]}" tee /etc/apt/sources.list.d/bookworm-backports.list >/dev/null
  else
    echo "setup: apt has no Debian 12 archive configured to take bookworm-backports from" >&2
  fi
fi
if ((${#missing[@]} + ${#backports[@]})); then
  echo "setup: installing ${missing[*]} ${backports[*]}"
  "${as_root[@]}" apt-get update -qq
fi
if ((${#missing[@]})); then
  DEBIAN_FRONTEND=noninteractive "${as_root[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi
if ((${#backports[@]})); then
  # Its dependencies (libdrm, the other Mesa packages present) come along from there too.
  # Where backports cannot be had, Debian 12's own Mesa does the same work, more slowly.
  DEBIAN_FRONTEND=noninteractive "${as_root[@]}" apt-get install -y -qq --no-install-recommends \
    -t bookworm-backports "${backports[@]}" ||
    {
      echo "setup: no Mesa from bookworm-backports; installing Debian 12's (slower)" >&2
      DEBIAN_FRONTEND=noninteractive "${as_root[@]}" apt-get install -y -qq \
        --no-install-recommends "${backports[@]}"
    }
fi

# ONNX Runtime for the ONNX detector (serve --detector onnx): the shared library inside the
# onnxruntime wheel, unpacked into the cache directory where DigiView looks for it. Pinned, so
# every machine runs the same one; any 1.17 or newer works (ORT_DYLIB_PATH picks another).
onnxruntime_version=1.26.0
cache="${XDG_CACHE_HOME:-$HOME/.cache}/digiview"
if ! ls "$cache/onnxruntime/libonnxruntime.so.$onnxruntime_version" >/dev/null 2>&1; then
  echo "setup: fetching ONNX Runtime $onnxruntime_version (the onnxruntime wheel)"
  wheels=$(mktemp -d)
  python3 -m pip download --quiet --no-deps --only-binary=:all: \
    --dest "$wheels" "onnxruntime==$onnxruntime_version"
  mkdir -p "$cache/onnxruntime"
  python3 - "$wheels"/onnxruntime-*.whl "$cache/onnxruntime" <<'PY'
import sys, zipfile, os
wheel, dest = sys.argv[1], sys.argv[2]
with zipfile.ZipFile(wheel) as z:
    for name in z.namelist():
        base = os.path.basename(name)
        if name.startswith("onnxruntime/capi/") and base.startswith("libonnxruntime.so"):
            with z.open(name) as src, open(os.path.join(dest, base), "wb") as out:
                out.write(src.read())
PY
  rm -rf "$wheels"
  ls "$cache/onnxruntime/libonnxruntime.so.$onnxruntime_version" >/dev/null
fi
# The tests' photographs (person, dog, horses, kite, giraffe): Debian's darknet package's
# data, unpacked without installing it (it would bring OpenCV along).
if ! ls "$cache/darknet/usr/share/darknet/data/person.jpg" >/dev/null 2>&1; then
  echo "setup: fetching darknet's sample photographs"
  debs=$(mktemp -d)
  chmod 777 "$debs"
  (cd "$debs" && apt-get download darknet >/dev/null)
  dpkg-deb -x "$debs"/darknet_*.deb "$cache/darknet"
  rm -rf "$debs"
fi

# The peers users have, in the project's own Python environment (.venv): MAVSDK (its wheel
# carries the C++ core most apps build on), pymavlink, and MAVProxy as the router that joins
# an autopilot, DigiView and a ground station on a drone; and klvdata and stanag4609, MISB
# ST 0601 readers written by others (stanag4609 also reads ST 0903 VMTI), for the KLV
# metadata. Pinned, so every machine tests against the same
# ones; the tests find them at .venv/bin/python.
mavlink_peers=(mavsdk==4.1.0 pymavlink==2.4.50 MAVProxy==1.8.75 klvdata==0.0.3 stanag4609==0.4.0)
if ! .venv/bin/python -c 'import mavsdk, pymavlink, MAVProxy, klvdata, stanag4609' 2>/dev/null ||
  ! .venv/bin/pip freeze 2>/dev/null | grep -qx "${mavlink_peers[0]}"; then
  echo "setup: installing ${mavlink_peers[*]} into .venv"
  python3 -m venv .venv
  .venv/bin/pip install --quiet --disable-pip-version-check "${mavlink_peers[@]}"
fi

if ! command -v cargo >/dev/null; then
  echo "setup: no Rust toolchain: install Rust 1.95 or newer with rustup" >&2
  exit 1
fi
echo "setup: system packages present; $(cargo --version)"
