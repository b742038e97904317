// The packed mip levels the ingest and mip passes write into the level buffer (one row after
// another per level, bytes as the textures hold them; src/render/gpu/planes.rs lays them out),
// and the 2x2 average both make them with.
//
// Prepended to those passes' sources by src/render/gpu/shaders.rs.

// Where one level of one plane lies in the level buffer (bytes; offset and stride multiples of
// 256, as texture copies need).
struct Region {
    offset: u32,
    stride: u32,
    width: u32,
    height: u32,
}

// Byte k (0..7) of the eight bytes a | b.
fn byte8(a: u32, b: u32, k: u32) -> u32 {
    let w = select(b, a, k < 4u);
    return (w >> ((k & 3u) * 8u)) & 0xffu;
}

// One word of a coarser level from two rows of eight bytes of the finer one (a0 a1 above,
// b0 b1 below) with `ch` bytes per texel: each byte is the rounded mean (halves up, as
// src/render/mip.rs rounds) of its channel in the 2x2 texels under it.
fn halve(a0: u32, a1: u32, b0: u32, b1: u32, ch: u32) -> u32 {
    var out = 0u;
    for (var j = 0u; j < 4u; j++) {
        let k = 2u * ch * (j / ch) + j % ch;
        let sum = byte8(a0, a1, k) + byte8(a0, a1, k + ch) + byte8(b0, b1, k) + byte8(b0, b1, k + ch);
        out |= ((sum + 2u) / 4u) << (j * 8u);
    }
    return out;
}
