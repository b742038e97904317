// The live picture: the encoder's own H.264 (H.265 is said, not shown) over a WebSocket, decoded by the browser and drawn
// on a canvas. Each message is one access unit: a flags byte (bit 0: key frame), the
// presentation time in µs (u64, little-endian), then Annex B bytes. WebCodecs decodes it where
// the browser offers it (a secure context: https, or localhost); elsewhere (plain http from
// another machine) Media Source Extensions play it as fragmented MP4. `?preview=mse` forces
// the second.

import { socketUrl } from './api.js';
import { nalUnits, initSegment, fragment } from './mp4.js';

// Units waiting to be decoded before the page gives up on them and skips to a key frame,
// which it asks the video head for: the picture stays live rather than late.
const MAX_BACKLOG = 2;
// Asking for key frames at most this often (ms): each one costs every viewer bits.
const KEY_ASK_INTERVAL = 1000;
// The MSE player's live edge: further behind than this (s), it jumps to the newest picture.
const MAX_BEHIND = 0.25;

// The codec string (avc1.PPCCLL) from the SPS of a key frame, or null.
function codecOf(units) {
  const sps = units.find((n) => (n[0] & 0x1f) === 7);
  const hex = (b) => b.toString(16).padStart(2, '0');
  return sps ? `avc1.${hex(sps[1])}${hex(sps[2])}${hex(sps[3])}` : null;
}

// WebCodecs: each unit straight to the browser's decoder.
class CodecsSink {
  constructor(preview) {
    this.preview = preview;
    this.decoder = null;
    this.codec = null;
  }

  backlog() {
    return this.decoder ? this.decoder.decodeQueueSize : 0;
  }

  push(key, timestamp, data, units) {
    const codec = key ? codecOf(units) : null;
    if (codec && (codec !== this.codec || !this.decoder || this.decoder.state === 'closed')) {
      if (this.decoder && this.decoder.state !== 'closed') this.decoder.close();
      this.codec = codec;
      this.decoder = new VideoDecoder({
        output: (frame) => {
          this.preview.draw(frame, frame.displayWidth, frame.displayHeight, frame.timestamp);
          frame.close();
        },
        error: (e) => this.preview.failed(e, () => { this.codec = null; }),
      });
      this.decoder.configure({ codec, optimizeForLatency: true });
    }
    if (!this.decoder || this.decoder.state !== 'configured') return false;
    this.decoder.decode(new EncodedVideoChunk({ type: key ? 'key' : 'delta', timestamp, data }));
    return true;
  }
}

// Media Source Extensions: a hidden video element fed fragmented MP4, each of its frames
// drawn on the canvas, held at the live edge.
class MseSink {
  constructor(preview) {
    this.preview = preview;
    this.video = document.createElement('video');
    Object.assign(this.video, { muted: true, playsInline: true, autoplay: true });
    this.sps = null;
    this.buffer = null;
    this.queue = [];
    this.sequence = 0;
    this.last = null;
    this.duration = 33333;
    this.times = []; // [media time, presentation time] of the recent units, µs
    this.watch();
  }

  watch() {
    const drawn = (now, meta) => {
      this.preview.draw(this.video, this.video.videoWidth, this.video.videoHeight, this.ptsAt(meta.mediaTime));
      this.video.requestVideoFrameCallback(drawn);
    };
    this.video.requestVideoFrameCallback(drawn);
  }

  backlog() {
    return this.queue.length;
  }

  // The stream's presentation time (µs) of the unit the media timeline plays at `media`
  // seconds (the timeline runs without the stream's gaps), or null.
  ptsAt(media) {
    const t = media * 1e6;
    let best = null;
    for (const [at, pts] of this.times) {
      if (best === null || Math.abs(at - t) < Math.abs(best[0] - t)) best = [at, pts];
    }
    return best && Math.abs(best[0] - t) < this.duration ? best[1] : null;
  }

  // A new stream (first key frame, or new parameter sets): a new MediaSource.
  open(sps, pps, codec) {
    const init = initSegment(sps, pps);
    const source = new MediaSource();
    this.sps = sps.join();
    this.buffer = null;
    this.queue = [init.segment];
    this.time = 0;
    source.addEventListener('sourceopen', () => {
      URL.revokeObjectURL(this.video.src);
      this.buffer = source.addSourceBuffer(`video/mp4; codecs="${codec}"`);
      this.buffer.mode = 'segments';
      this.buffer.addEventListener('updateend', () => this.feed());
      this.buffer.addEventListener('error', () => this.preview.failed(new Error('the video element refused the stream'), () => { this.sps = null; }));
      this.feed();
    }, { once: true });
    this.video.src = URL.createObjectURL(source);
    this.video.play().catch(() => {});
  }

  push(key, timestamp, data, units) {
    if (key) {
      const sps = units.find((n) => (n[0] & 0x1f) === 7);
      const pps = units.find((n) => (n[0] & 0x1f) === 8);
      if (sps && pps && sps.join() !== this.sps) this.open(sps, pps, codecOf(units));
    }
    if (this.sps === null) return false;
    // The media timeline runs without gaps even where units were skipped (the player would
    // stop at a gap): each unit lasts as long as the one before it did.
    const gap = this.last !== null ? timestamp - this.last : 0;
    if (gap > 0 && gap < 200000) this.duration = gap;
    this.last = timestamp;
    this.queue.push(fragment(++this.sequence, key, this.time, this.duration, units));
    this.times.push([this.time, timestamp]);
    if (this.times.length > 120) this.times.shift();
    this.time += this.duration;
    this.feed();
    return true;
  }

  feed() {
    const b = this.buffer;
    if (!b || b.updating) return;
    const v = this.video;
    if (v.buffered.length > 0) {
      const end = v.buffered.end(v.buffered.length - 1);
      // Behind the newest picture: played faster until caught up (a seek would stall on
      // decoding from the last key frame).
      const behind = end - v.currentTime;
      if (behind > 2) v.currentTime = end - 0.05;
      else v.playbackRate = behind > MAX_BEHIND ? 1.5 : behind > 0.1 ? 1.1 : 1;
      // Keep a few seconds behind the playhead, no more.
      if (v.currentTime - v.buffered.start(0) > 10) {
        b.remove(0, v.currentTime - 3);
        return;
      }
    }
    const next = this.queue.shift();
    if (next) b.appendBuffer(next);
    if (v.paused) v.play().catch(() => {});
  }
}

export class Preview extends EventTarget {
  constructor(canvas, note) {
    super();
    this.canvas = canvas;
    this.context = canvas.getContext('2d');
    this.note = note;
    this.frames = 0;
    this.mode = null;
    this.sink = null;
    this.socket = null;
    this.waitingForKey = true;
    this.askedAt = 0;
  }

  start() {
    const forced = new URLSearchParams(location.search).get('preview');
    const mse = 'MediaSource' in window && MediaSource.isTypeSupported('video/mp4; codecs="avc1.42e01f"');
    if ('VideoDecoder' in window && forced !== 'mse') {
      this.mode = 'webcodecs';
      this.sink = new CodecsSink(this);
    } else if (mse) {
      this.mode = 'mse';
      this.sink = new MseSink(this);
    } else {
      this.show('No preview: this browser decodes neither WebCodecs nor MSE video. The RTSP stream plays in any player.');
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
      this.socket = null;
      setTimeout(() => this.connect(), 1000);
    };
    this.socket = socket;
  }

  // Skips to the next key frame, asking the video head for one (not too often).
  skip() {
    this.waitingForKey = true;
    const now = performance.now();
    if (this.socket && now - this.askedAt > KEY_ASK_INTERVAL) {
      this.askedAt = now;
      this.socket.send('key');
    }
  }

  unit(bytes) {
    const key = (bytes[0] & 1) === 1;
    const timestamp = Number(new DataView(bytes.buffer, bytes.byteOffset + 1, 8).getBigUint64(0, true));
    const data = bytes.subarray(9);
    if (key) this.waitingForKey = false;
    if (this.waitingForKey) return;
    if (this.sink.backlog() > MAX_BACKLOG) {
      this.skip();
      return;
    }
    const units = key || this.mode === 'mse' ? nalUnits(data) : null;
    // H.265 (its VPS leads each key frame): the page previews H.264 only, which every
    // browser decodes; the RTSP streams carry the H.265.
    if (key && units.some((n) => n[0] === 0x40 && n[1] === 0x01)) {
      this.show('the stream is H.265, which this page does not preview: play the RTSP stream');
      this.waitingForKey = true;
      return;
    }
    if (!this.sink.push(key, timestamp, data, units)) this.waitingForKey = true;
  }

  failed(error, reset) {
    this.show(`decoding failed: ${error.message}`);
    reset();
    this.waitingForKey = true;
  }

  // Draws a decoded frame, presented at `pts` µs in the stream (null: not known), and tells
  // the listeners ('frame': { frames, pts }).
  draw(image, w, h, pts) {
    if (!w || !h) return;
    if (this.canvas.width !== w || this.canvas.height !== h) {
      this.canvas.width = w;
      this.canvas.height = h;
      this.dispatchEvent(new CustomEvent('resize', { detail: { width: w, height: h } }));
    }
    this.context.drawImage(image, 0, 0);
    this.frames++;
    if (this.frames === 1) this.show('');
    this.dispatchEvent(new CustomEvent('frame', { detail: { frames: this.frames, pts: pts ?? null } }));
  }
}
