// Fragmented MP4 from H.264 access units, for browsers that play the preview through Media
// Source Extensions (a page opened over plain http from another machine, where WebCodecs is
// not offered): one initialisation segment from a key frame's SPS and PPS, then one fragment
// (moof + mdat) per access unit. ISO/IEC 14496-12 and 14496-15.

const TIMESCALE = 1000000; // µs, the units' own presentation times

function concat(parts) {
  const out = new Uint8Array(parts.reduce((n, p) => n + p.length, 0));
  let at = 0;
  for (const p of parts) {
    out.set(p, at);
    at += p.length;
  }
  return out;
}

// Big-endian fields: [bytes, value] pairs, values up to 2^53.
function fields(...list) {
  const out = new Uint8Array(list.reduce((n, [bytes]) => n + bytes, 0));
  const view = new DataView(out.buffer);
  let at = 0;
  for (const [bytes, value] of list) {
    if (bytes === 8) {
      view.setUint32(at, Math.floor(value / 2 ** 32));
      view.setUint32(at + 4, value % 2 ** 32);
    } else if (bytes === 4) view.setUint32(at, value);
    else if (bytes === 2) view.setUint16(at, value);
    else view.setUint8(at, value);
    at += bytes;
  }
  return out;
}

function box(type, ...parts) {
  const body = concat(parts);
  const head = fields([4, 8 + body.length]);
  return concat([head, new TextEncoder().encode(type), body]);
}

const full = (type, version, flags, ...parts) => box(type, fields([1, version], [1, flags >> 16], [2, flags & 0xffff]), ...parts);
const zeros = (n) => new Uint8Array(n);
const MATRIX = fields([4, 0x10000], [4, 0], [4, 0], [4, 0], [4, 0x10000], [4, 0], [4, 0], [4, 0], [4, 0x40000000]);

// The NAL units of an Annex B access unit.
export function nalUnits(data) {
  const starts = [];
  for (let i = 0; i + 2 < data.length; i++) {
    if (data[i] === 0 && data[i + 1] === 0 && data[i + 2] === 1) {
      starts.push(i + 3);
      i += 2;
    }
  }
  return starts.map((s, k) => {
    let end = k + 1 < starts.length ? starts[k + 1] - 3 : data.length;
    while (end > s && data[end - 1] === 0) end--; // a four-byte start code's leading zero
    return data.subarray(s, end);
  });
}

// Exp-Golomb reader over an RBSP (emulation prevention bytes removed).
class Bits {
  constructor(nal) {
    const bytes = [];
    for (let i = 1; i < nal.length; i++) {
      if (i >= 3 && nal[i] === 3 && nal[i - 1] === 0 && nal[i - 2] === 0) continue;
      bytes.push(nal[i]);
    }
    this.bytes = bytes;
    this.at = 0;
  }

  bit() {
    const b = (this.bytes[this.at >> 3] >> (7 - (this.at & 7))) & 1;
    this.at++;
    return b;
  }

  bits(n) {
    let v = 0;
    for (let i = 0; i < n; i++) v = v * 2 + this.bit();
    return v;
  }

  ue() {
    let zeros = 0;
    while (this.bit() === 0 && zeros < 32) zeros++;
    return 2 ** zeros - 1 + this.bits(zeros);
  }

  se() {
    const v = this.ue();
    return v % 2 ? (v + 1) / 2 : -v / 2;
  }
}

// The picture size an SPS describes (H.264 7.3.2.1.1), cropping applied.
export function spsSize(sps) {
  const r = new Bits(sps);
  const profile = r.bits(8);
  r.bits(16); // constraint flags, level
  r.ue(); // seq_parameter_set_id
  let chroma = 1;
  if ([100, 110, 122, 244, 44, 83, 86, 118, 128, 138, 139, 134, 135].includes(profile)) {
    chroma = r.ue();
    if (chroma === 3) r.bit();
    r.ue();
    r.ue();
    r.bit();
    if (r.bit()) {
      for (let i = 0; i < (chroma === 3 ? 12 : 8); i++) {
        if (!r.bit()) continue;
        let last = 8;
        let next = 8;
        for (let j = 0; j < (i < 6 ? 16 : 64) && next !== 0; j++) {
          next = (last + r.se() + 256) % 256;
          last = next === 0 ? last : next;
        }
      }
    }
  }
  r.ue(); // log2_max_frame_num_minus4
  const pocType = r.ue();
  if (pocType === 0) r.ue();
  else if (pocType === 1) {
    r.bit();
    r.se();
    r.se();
    const n = r.ue();
    for (let i = 0; i < n; i++) r.se();
  }
  r.ue(); // max_num_ref_frames
  r.bit();
  const widthMbs = r.ue() + 1;
  const heightUnits = r.ue() + 1;
  const frameMbsOnly = r.bit();
  if (!frameMbsOnly) r.bit();
  r.bit(); // direct_8x8_inference_flag
  let width = widthMbs * 16;
  let height = heightUnits * 16 * (2 - frameMbsOnly);
  if (r.bit()) {
    const [left, right, top, bottom] = [r.ue(), r.ue(), r.ue(), r.ue()];
    const cropX = chroma === 1 || chroma === 2 ? 2 : 1;
    const cropY = (chroma === 1 ? 2 : 1) * (2 - frameMbsOnly);
    width -= (left + right) * cropX;
    height -= (top + bottom) * cropY;
  }
  return { width, height };
}

// The initialisation segment for a stream with this SPS and PPS.
export function initSegment(sps, pps) {
  const { width, height } = spsSize(sps);
  const avcC = box('avcC', fields([1, 1], [1, sps[1]], [1, sps[2]], [1, sps[3]], [1, 0xff], [1, 0xe1], [2, sps.length]),
    sps, fields([1, 1], [2, pps.length]), pps);
  const avc1 = box('avc1', zeros(6), fields([2, 1]), zeros(16), fields([2, width], [2, height],
    [4, 0x480000], [4, 0x480000], [4, 0], [2, 1]), zeros(32), fields([2, 0x18], [2, 0xffff]), avcC);
  const stbl = box('stbl', full('stsd', 0, 0, fields([4, 1]), avc1), full('stts', 0, 0, fields([4, 0])),
    full('stsc', 0, 0, fields([4, 0])), full('stsz', 0, 0, fields([4, 0], [4, 0])), full('stco', 0, 0, fields([4, 0])));
  const minf = box('minf', full('vmhd', 0, 1, zeros(8)),
    box('dinf', full('dref', 0, 0, fields([4, 1]), full('url ', 0, 1))), stbl);
  const mdia = box('mdia', full('mdhd', 0, 0, fields([4, 0], [4, 0], [4, TIMESCALE], [4, 0], [2, 0x55c4], [2, 0])),
    full('hdlr', 0, 0, fields([4, 0]), new TextEncoder().encode('vide'), zeros(12), new TextEncoder().encode('DigiView\0')), minf);
  const tkhd = full('tkhd', 0, 3, fields([4, 0], [4, 0], [4, 1], [4, 0], [4, 0]), zeros(8),
    fields([2, 0], [2, 0], [2, 0], [2, 0]), MATRIX, fields([4, width * 65536], [4, height * 65536]));
  const mvhd = full('mvhd', 0, 0, fields([4, 0], [4, 0], [4, 1000], [4, 0], [4, 0x10000], [2, 0x100]), zeros(10),
    MATRIX, zeros(24), fields([4, 2]));
  const mvex = box('mvex', full('trex', 0, 0, fields([4, 1], [4, 1], [4, 0], [4, 0], [4, 0])));
  const ftyp = box('ftyp', new TextEncoder().encode('isom'), fields([4, 0x200]), new TextEncoder().encode('isomiso6avc1mp41'));
  return { segment: concat([ftyp, box('moov', mvhd, box('trak', tkhd, mdia), mvex)]), width, height };
}

// One access unit's fragment: the unit's NAL units length-prefixed, parameter sets and
// delimiters left out (they are in the initialisation segment).
export function fragment(sequence, key, time, duration, units) {
  const kept = units.filter((n) => ![7, 8, 9].includes(n[0] & 0x1f));
  const data = concat(kept.flatMap((n) => [fields([4, n.length]), n]));
  const flags = key ? 0x02000000 : 0x01010000;
  const trunFields = (offset) => fields([4, 1], [4, offset], [4, duration], [4, data.length], [4, flags]);
  const moof = (offset) => box('moof', full('mfhd', 0, 0, fields([4, sequence])),
    box('traf', full('tfhd', 0, 0x20000, fields([4, 1])), full('tfdt', 1, 0, fields([8, time])),
      full('trun', 0, 0x701, trunFields(offset))));
  const size = moof(0).length;
  return concat([moof(size + 8), box('mdat', data)]);
}
