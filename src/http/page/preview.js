// The live picture: the encoder's own H.264 over a WebSocket, decoded by the browser
// (WebCodecs) and drawn on a canvas. Each message is one access unit: a flags byte (bit 0: key
// frame), the presentation time in µs (u64, little-endian), then Annex B bytes.

import { socketUrl } from './api.js';

// The codec string (avc1.PPCCLL) from the SPS of a key frame, or null.
function codecOf(data) {
  for (let i = 0; i + 7 < data.length; i++) {
    if (data[i] === 0 && data[i + 1] === 0 && data[i + 2] === 1 && (data[i + 3] & 0x1f) === 7) {
      const hex = (b) => b.toString(16).padStart(2, '0');
      return `avc1.${hex(data[i + 4])}${hex(data[i + 5])}${hex(data[i + 6])}`;
    }
  }
  return null;
}

export class Preview extends EventTarget {
  constructor(canvas, note) {
    super();
    this.canvas = canvas;
    this.context = canvas.getContext('2d');
    this.note = note;
    this.frames = 0;
    this.codec = null;
    this.decoder = null;
    this.waitingForKey = true;
  }

  start() {
    if (!('VideoDecoder' in window)) {
      const why = window.isSecureContext
        ? 'this browser cannot decode video with WebCodecs'
        : 'the preview needs a secure context: open this page as https:// or through localhost';
      this.show(`No preview: ${why}. The RTSP stream plays in any player.`);
      return;
    }
    this.show('waiting for the picture…');
    this.connect();
  }

  show(text) {
    this.note.textContent = text;
    this.note.hidden = !text;
  }

  connect() {
    const socket = new WebSocket(socketUrl('/api/preview'));
    socket.binaryType = 'arraybuffer';
    socket.onmessage = (event) => this.unit(new Uint8Array(event.data));
    socket.onclose = () => {
      this.waitingForKey = true;
      setTimeout(() => this.connect(), 1000);
    };
  }

  unit(bytes) {
    const key = (bytes[0] & 1) === 1;
    const timestamp = Number(new DataView(bytes.buffer, bytes.byteOffset + 1, 8).getBigUint64(0, true));
    const data = bytes.subarray(9);
    if (key) {
      const codec = codecOf(data);
      if (codec && (codec !== this.codec || !this.decoder || this.decoder.state === 'closed')) {
        this.configure(codec);
      }
      this.waitingForKey = false;
    }
    if (this.waitingForKey || !this.decoder) return;
    // A decoder that falls behind drops what it has not started and waits for a key frame:
    // the picture stays live rather than late.
    if (this.decoder.decodeQueueSize > 4) {
      this.waitingForKey = true;
      return;
    }
    this.decoder.decode(new EncodedVideoChunk({ type: key ? 'key' : 'delta', timestamp, data }));
  }

  configure(codec) {
    if (this.decoder && this.decoder.state !== 'closed') this.decoder.close();
    this.codec = codec;
    this.decoder = new VideoDecoder({
      output: (frame) => this.draw(frame),
      error: (e) => {
        this.show(`decoding failed: ${e.message}`);
        this.waitingForKey = true;
        this.codec = null;
      },
    });
    this.decoder.configure({ codec, optimizeForLatency: true });
  }

  draw(frame) {
    const { displayWidth: w, displayHeight: h } = frame;
    if (this.canvas.width !== w || this.canvas.height !== h) {
      this.canvas.width = w;
      this.canvas.height = h;
      this.dispatchEvent(new CustomEvent('resize', { detail: { width: w, height: h } }));
    }
    this.context.drawImage(frame, 0, 0);
    frame.close();
    this.frames++;
    if (this.frames === 1) this.show('');
    this.dispatchEvent(new CustomEvent('frame', { detail: { frames: this.frames } }));
  }
}
