"""OpenCV's capture of an RTSP stream, each decoded frame written to stdout as grey bytes:
the client `examples/glass_to_glass.rs --opencv` times. FFmpeg's RTSP client and H.264
decoder as a library, set for low latency as its users are told to (no input buffering, the
decoder's low-delay flag, TCP) and with one decoding thread: OpenCV's default, a thread per
core, decodes a frame a frame interval late.

Usage: .venv/bin/python scripts/cv_frames.py URL
"""

import os
import sys

os.environ.setdefault(
    "OPENCV_FFMPEG_CAPTURE_OPTIONS", "rtsp_transport;tcp|fflags;nobuffer|flags;low_delay"
)
import cv2  # noqa: E402  (reads the options above when it opens a capture)

capture = cv2.VideoCapture(sys.argv[1], cv2.CAP_FFMPEG, [cv2.CAP_PROP_N_THREADS, 1])
if not capture.isOpened():
    sys.exit(f"cv_frames: OpenCV cannot open {sys.argv[1]}")
out = sys.stdout.buffer
while True:
    ok, frame = capture.read()
    if not ok:
        break
    out.write(cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY).tobytes())
    out.flush()
