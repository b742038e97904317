// Upload, second half: mip levels 1 and 2 of the frame's planes from its raw bytes (RGBA8,
// I420 or NV12, as one array of words), written as packed rows into the level buffer that the
// renderer then copies into the planes' textures. Level 0 of each plane is copied straight
// from the frame (src/render/gpu/renderer.rs), so nothing here is done per input pixel; only
// I420's chroma is woven here into the Cb Cr pairs NV12 has.
//
// The planes (src/render/gpu/planes.rs; src/render/mip.rs is the twin): RGBA, or for 4:2:0
// input the luma and the half-size chroma. Each plane's level k + 1 averages 2x2 texels of
// its level k, per channel, in integer code values rounded half up.
//
// One invocation per 16x4 block of the frame: it reads whole words (rows are padded to 256
// bytes and the imaged box starts on a multiple of 32) and writes the words the block makes:
// for 4:2:0, 4 words of luma level 1, 1 of luma level 2 and 2 of chroma level 1 (and 8 of
// woven chroma for I420). Only the lens's imaged box is done (dispatched over it, from its
// origin); the level buffer keeps its black around it.

override INPUT_FORMAT: u32 = 0u;

// The regions the ingest writes.
struct Targets {
    // RGBA, or luma: levels 1 and 2.
    level1: Region,
    level2: Region,
    // Chroma: level 0 (woven from I420's planes), level 1.
    chroma0: Region,
    chroma1: Region,
    // The lens's imaged box: first column and row, and past the last (Lens::imaged_box).
    imaged: vec4u,
}

@group(0) @binding(0) var<uniform> params: Params;
// The frame's bytes, padded by 16 so that reading a row's last block never leaves the buffer.
@group(0) @binding(1) var<storage, read> raw: array<u32>;
@group(0) @binding(2) var<storage, read_write> levels: array<u32>;
@group(0) @binding(3) var<uniform> targets: Targets;

// Word `i` of row `y` of a region (rows past its height are not written).
fn put(r: Region, y: u32, i: u32, w: u32) {
    if y < r.height {
        levels[(r.offset + y * r.stride) / 4u + i] = w;
    }
}

// The frame's row y from byte `x` on, as a word index; rows past the bottom read the last.
fn at(plane: u32, stride: u32, rows: u32, y: u32, x: u32) -> u32 {
    return (plane + min(y, rows - 1u) * stride + x) / 4u;
}

@compute @workgroup_size(8, 8)
fn ingest(@builtin(global_invocation_id) gid: vec3u) {
    let x0 = gid.x * 16u + targets.imaged.x;
    let y0 = gid.y * 4u + targets.imaged.y;
    if x0 >= targets.imaged.z || y0 >= targets.imaged.w {
        return;
    }
    let h = params.input.y;
    let stride = params.input.z;
    if INPUT_FORMAT == FORMAT_RGBA {
        // Level 1: 8 texels in each of 2 rows, a word each; level 2: 4 texels in 1 row.
        var l1: array<u32, 16>;
        for (var r = 0u; r < 2u; r++) {
            let top = at(0u, stride, h, y0 + 2u * r, x0 * 4u);
            let bottom = at(0u, stride, h, y0 + 2u * r + 1u, x0 * 4u);
            for (var i = 0u; i < 8u; i++) {
                let w = halve(raw[top + 2u * i], raw[top + 2u * i + 1u], raw[bottom + 2u * i], raw[bottom + 2u * i + 1u], 4u);
                l1[r * 8u + i] = w;
                put(targets.level1, y0 / 2u + r, x0 / 2u + i, w);
            }
        }
        for (var i = 0u; i < 4u; i++) {
            let w = halve(l1[2u * i], l1[2u * i + 1u], l1[8u + 2u * i], l1[9u + 2u * i], 4u);
            put(targets.level2, y0 / 4u, x0 / 4u + i, w);
        }
        return;
    }
    // Luma level 1: 8 texels (2 words) in each of 2 rows; level 2: 4 texels (1 word).
    var l1: array<u32, 4>;
    for (var r = 0u; r < 2u; r++) {
        let top = at(0u, stride, h, y0 + 2u * r, x0);
        let bottom = at(0u, stride, h, y0 + 2u * r + 1u, x0);
        for (var i = 0u; i < 2u; i++) {
            let w = halve(raw[top + 2u * i], raw[top + 2u * i + 1u], raw[bottom + 2u * i], raw[bottom + 2u * i + 1u], 1u);
            l1[r * 2u + i] = w;
            put(targets.level1, y0 / 2u + r, x0 / 8u + i, w);
        }
    }
    put(targets.level2, y0 / 4u, x0 / 16u, halve(l1[0], l1[1], l1[2], l1[3], 1u));
    // Chroma: rows y0 / 2 and y0 / 2 + 1 of the half-size plane, 8 Cb Cr pairs (4 words)
    // each.
    let cs = params.input.w;
    let ch = h / 2u;
    let cy = y0 / 2u;
    var uv: array<u32, 8>;
    for (var r = 0u; r < 2u; r++) {
        if INPUT_FORMAT == FORMAT_I420 {
            let u = at(params.input_planes.x, cs, ch, cy + r, x0 / 2u);
            let v = at(params.input_planes.y, cs, ch, cy + r, x0 / 2u);
            for (var i = 0u; i < 2u; i++) {
                uv[r * 4u + 2u * i] = weave(raw[u + i], raw[v + i]);
                uv[r * 4u + 2u * i + 1u] = weave(raw[u + i] >> 16u, raw[v + i] >> 16u);
            }
            for (var i = 0u; i < 4u; i++) {
                put(targets.chroma0, cy + r, x0 / 4u + i, uv[r * 4u + i]);
            }
        } else {
            let a = at(params.input_planes.x, cs, ch, cy + r, x0);
            for (var i = 0u; i < 4u; i++) {
                uv[r * 4u + i] = raw[a + i];
            }
        }
    }
    put(targets.chroma1, cy / 2u, x0 / 8u, halve(uv[0], uv[1], uv[4], uv[5], 2u));
    put(targets.chroma1, cy / 2u, x0 / 8u + 1u, halve(uv[2], uv[3], uv[6], uv[7], 2u));
}

// The Cb Cr pairs of two Cb and two Cr samples (the low half of each word): u0 v0 u1 v1.
fn weave(u: u32, v: u32) -> u32 {
    return (u & 0xffu) | ((v & 0xffu) << 8u) | ((u & 0xff00u) << 8u) | ((v & 0xff00u) << 16u);
}
