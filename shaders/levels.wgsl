// The packed mip levels the ingest and mip passes write into the level buffer (one row after
// another per level, bytes as the textures hold them; src/render/gpu/planes/mod.rs lays them out),
// and the 2x2 average both make them with.
//
// Prepended to those passes' sources by src/render/gpu/shaders.rs.

// Where one level of one plane lies in the level buffer (bytes; offset and stride multiples of
// 256, as texture copies need): twin of the Rust `Region` (src/render/gpu/planes/mod.rs).
struct Region {
    offset: u32,
    stride: u32,
    width: u32,
    height: u32,
}

// One word of a coarser level from two rows of two words of the finer one (a0 a1 above, b0 b1
// below) with `ch` bytes per texel (1, 2 or 4): each byte is the rounded mean (halves up, as
// src/render/mip.rs rounds) of its channel in the 2x2 texels under it. Bytes are summed in
// pairs inside 16-bit lanes of a word, which four bytes of at most 255 never overflow.
fn halve(a0: u32, a1: u32, b0: u32, b1: u32, ch: u32) -> u32 {
    if ch == 4u {
        // One texel from four: R B and G A sums side by side.
        let rb = even(a0) + even(a1) + even(b0) + even(b1);
        let ga = odd(a0) + odd(a1) + odd(b0) + odd(b1);
        return rounded(rb) | (rounded(ga) << 8u);
    }
    if ch == 2u {
        // One Cb Cr texel from each word's two (above and below).
        return pair(a0, b0) | (pair(a1, b1) << 16u);
    }
    // Two luma texels from each word's four.
    let lo = rounded(even(a0) + odd(a0) + even(b0) + odd(b0));
    let hi = rounded(even(a1) + odd(a1) + even(b1) + odd(b1));
    return (lo & 0xffu) | ((lo >> 8u) & 0xff00u) | ((hi & 0xffu) << 16u) | ((hi << 8u) & 0xff000000u);
}

// Bytes 0 and 2, and 1 and 3, of a word in its two 16-bit lanes.
fn even(w: u32) -> u32 {
    return w & 0x00ff00ffu;
}

fn odd(w: u32) -> u32 {
    return (w >> 8u) & 0x00ff00ffu;
}

// Sums of four in each 16-bit lane → their rounded means, in bytes 0 and 2.
fn rounded(sums: u32) -> u32 {
    return ((sums + 0x00020002u) >> 2u) & 0x00ff00ffu;
}

// The Cb Cr texel (2 bytes) averaging the two texels of word a and the two of word b.
fn pair(a: u32, b: u32) -> u32 {
    // Cb sums in lane 0 and Cr sums in lane 1 of `s`, after adding each word's two texels.
    let cb = even(a) + even(b);
    let cr = odd(a) + odd(b);
    let s = ((cb & 0xffffu) + (cb >> 16u)) | (((cr & 0xffffu) + (cr >> 16u)) << 16u);
    let m = rounded(s);
    return (m & 0xffu) | ((m >> 8u) & 0xff00u);
}
