#!/usr/bin/env bash
# Packs what scripts/gpu_figures.sh runs into one archive for a machine that has a GPU and
# its driver but neither the Rust toolchain nor GStreamer (a rented cloud GPU, a CI runner):
# the release `digiview` and `glass_to_glass` (stripped), the GStreamer plugins they load
# with every library those need (the C library excepted), the plugin scanner, the Vulkan
# loader, lens-cal/ and the figures script. On that machine:
#
#     tar xzf digiview-gpu.tar.gz && bundle/run.sh [LOG_DIR]
#
# Usage: scripts/gpu_bundle.sh [ARCHIVE]   (default target/digiview-gpu.tar.gz)
set -euo pipefail
cd "$(dirname "$0")/.."
archive="$(realpath -m "${1:-target/digiview-gpu.tar.gz}")"
cargo build --release --locked --quiet --bin digiview --example glass_to_glass

multiarch=$(gcc -dumpmachine 2>/dev/null || echo x86_64-linux-gnu)
plugins=/usr/lib/$multiarch/gstreamer-1.0
scanner=/usr/lib/$multiarch/gstreamer1.0/gstreamer-1.0/gst-plugin-scanner
# The elements `serve` (image source, x264 or NVENC, RTSP, recordings, motion detection) and
# the latency client (RTSP, a hardware or software H.264 decoder) use; MPEG-TS for the KLV.
wanted=(coreelements app videoconvertscale x264 x265 nvcodec openh264
  videoparsersbad rtp rtpmanager rtsp udp tcp isomp4 typefindfunctions playback png
  imagefreeze multifile jpeg mpegtsmux)

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
b=$work/bundle
mkdir -p "$b/release/examples" "$b/lib" "$b/gst" "$b/bin"
strip -o "$b/release/digiview" target/release/digiview
strip -o "$b/release/examples/glass_to_glass" target/release/examples/glass_to_glass
for p in "${wanted[@]}"; do
  f=$plugins/libgst$p.so
  if [[ -f $f ]]; then cp "$f" "$b/gst/"; else echo "gpu_bundle: no $f (skipped)" >&2; fi
done
cp "$scanner" "$b/bin/"
cp "$(command -v gst-launch-1.0)" "$(command -v gst-inspect-1.0)" "$b/bin/"
# Every library any of them loads, but the C library's own, which the machine has.
libc='^(linux-vdso|libc|libm|libdl|libpthread|librt|ld-linux-x86-64)\.so'
for f in "$b"/release/digiview "$b"/release/examples/glass_to_glass "$b"/gst/*.so "$b"/bin/*; do
  ldd "$f" 2>/dev/null | awk '$2 == "=>" && $3 ~ /^\// {print $3}'
done | sort -u | while read -r lib; do
  [[ $(basename "$lib") =~ $libc ]] || cp -L "$lib" "$b/lib/"
done
vulkan=$(ldconfig -p | awk '/libvulkan\.so\.1 .*x86-64/ && !f {f = $NF} END {print f}')
[[ -n $vulkan ]] && cp -L "$vulkan" "$b/lib/"
# The GL backend loads EGL (GLVND's dispatcher) at run time; the machine's driver brings its
# own vendor library.
egl=$(ldconfig -p | awk '/libEGL\.so\.1 .*x86-64/ && !f {f = $NF} END {print f}')
if [[ -n $egl ]]; then
  for lib in "$egl" $(ldd "$egl" | awk '$2 == "=>" && $3 ~ /^\// {print $3}'); do
    [[ $(basename "$lib") =~ $libc ]] || cp -L "$lib" "$b/lib/"
  done
fi
cp -r lens-cal scripts/gpu_figures.sh scripts/serve_views.sh scripts/serve_config.sh "$b/"
cat >"$b/run.sh" <<'EOF'
#!/usr/bin/env bash
# Runs gpu_figures.sh on this bundle's binaries, libraries and plugins alone.
here="$(cd "$(dirname "$0")" && pwd)"
export LD_LIBRARY_PATH="$here/lib:/usr/local/nvidia/lib64:/usr/lib/x86_64-linux-gnu${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
export GST_PLUGIN_SYSTEM_PATH_1_0="$here/gst" GST_PLUGIN_PATH_1_0=
export GST_PLUGIN_SCANNER_1_0="$here/bin/gst-plugin-scanner" GST_REGISTRY_1_0=/tmp/digiview-gst-registry.bin
export PATH="$here/bin:$PATH"
icd=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
[[ -f $icd && -z ${VK_DRIVER_FILES:-} ]] && export VK_DRIVER_FILES=$icd
egl=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json
[[ -f $egl ]] && export __EGL_VENDOR_LIBRARY_FILENAMES=$egl
cd "$here" && exec bash gpu_figures.sh "$here/release" "$@"
EOF
chmod +x "$b/run.sh"
tar czf "$archive" -C "$work" bundle
echo "gpu_bundle: $archive ($(du -h "$archive" | cut -f1))"
