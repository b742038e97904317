#!/usr/bin/env bash
# Installs the system packages DigiView needs that this Debian machine lacks (as root, or
# through sudo), and checks the Rust toolchain. Safe to run again: it installs only what is
# missing.
set -euo pipefail

packages=(
  build-essential pkg-config
  # Vulkan and Mesa's lavapipe software driver: the GPU path runs on it where no GPU is.
  libvulkan1 mesa-vulkan-drivers vulkan-tools
  # GStreamer: decoding, H.264 encoding and the RTSP server.
  libgstreamer1.0-dev libgstreamer-plugins-base1.0-dev libgstrtspserver-1.0-dev
  gstreamer1.0-plugins-base gstreamer1.0-plugins-good gstreamer1.0-plugins-bad
  gstreamer1.0-plugins-ugly gstreamer1.0-libav gstreamer1.0-tools
  # ffprobe and ffplay: a second RTSP client in the tests, and FFmpeg's v360 for comparison.
  ffmpeg
)

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done

if ((${#missing[@]})); then
  echo "setup: installing ${missing[*]}"
  as_root=()
  if [ "$(id -u)" != 0 ]; then
    command -v sudo >/dev/null || { echo "setup: run as root (or install sudo) to install: ${missing[*]}" >&2; exit 1; }
    as_root=(sudo)
  fi
  "${as_root[@]}" apt-get update -qq
  DEBIAN_FRONTEND=noninteractive "${as_root[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

if ! command -v cargo >/dev/null; then
  echo "setup: no Rust toolchain: install Rust 1.95 or newer with rustup (https://rustup.rs)" >&2
  exit 1
fi
echo "setup: system packages present; $(cargo --version)"
