// Upload, second half, for the mip filter: mip levels 1 and 2 of the frame's planes from its
// raw bytes (RGBA8 or NV12, as one array of words; I420 arrives woven into NV12 by the copy
// into the upload buffer), written as packed rows into the level buffer that the renderer then
// copies into the planes' textures. Level 0 of each plane is copied straight from the frame
// (src/render/gpu/input.rs), so nothing here is done per input pixel.
//
// On a software rasterizer the host makes the same bytes instead (SourcePlanes::make_levels
// in src/render/gpu/planes/host_levels.rs, which tests/gpu_frames.rs holds to this pass and
// shaders/mip.wgsl).
//
// The planes (src/render/gpu/planes/mod.rs; src/render/mip.rs is the twin): RGBA, or for 4:2:0
// input the luma and the half-size chroma. Each plane's level k + 1 averages 2x2 texels of
// its level k, per channel, in integer code values rounded half up.
//
// One invocation per 16x4 block of the frame: it reads whole words (rows are padded to 256
// bytes and the imaged box starts on a multiple of 32) and writes the words the block makes:
// for 4:2:0, 4 words of luma level 1, 1 of luma level 2 and 2 of chroma level 1. Only the
// lens's imaged box is done (dispatched over it, from its origin); the level buffer keeps its
// black around it.

override INPUT_FORMAT: u32 = 0u;

// The regions the ingest writes: twin of the Rust `IngestTargets`
// (src/render/gpu/planes/mod.rs).
struct Targets {
    // RGBA, or luma: levels 1 and 2.
    level1: Region,
    level2: Region,
    // Chroma: level 1.
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
    luma_levels(x0, y0);
    // Chroma: rows y0 / 2 and y0 / 2 + 1 of the half-size plane, 8 Cb Cr pairs (4 words)
    // each.
    let cy = y0 / 2u;
    let upper = chroma_row(cy, x0);
    let lower = chroma_row(cy + 1u, x0);
    put(targets.chroma1, cy / 2u, x0 / 8u, halve(upper.x, upper.y, lower.x, lower.y, 2u));
    put(targets.chroma1, cy / 2u, x0 / 8u + 1u, halve(upper.z, upper.w, lower.z, lower.w, 2u));
}

// Luma levels 1 (8 texels, 2 words, in each of 2 rows) and 2 (4 texels, 1 word) of the 16x4
// block at (x0, y0).
fn luma_levels(x0: u32, y0: u32) {
    let h = params.input.y;
    let stride = params.input.z;
    let t0 = at(0u, stride, h, y0, x0);
    let t1 = at(0u, stride, h, y0 + 1u, x0);
    let t2 = at(0u, stride, h, y0 + 2u, x0);
    let t3 = at(0u, stride, h, y0 + 3u, x0);
    let a0 = halve(raw[t0], raw[t0 + 1u], raw[t1], raw[t1 + 1u], 1u);
    let a1 = halve(raw[t0 + 2u], raw[t0 + 3u], raw[t1 + 2u], raw[t1 + 3u], 1u);
    let b0 = halve(raw[t2], raw[t2 + 1u], raw[t3], raw[t3 + 1u], 1u);
    let b1 = halve(raw[t2 + 2u], raw[t2 + 3u], raw[t3 + 2u], raw[t3 + 3u], 1u);
    put(targets.level1, y0 / 2u, x0 / 8u, a0);
    put(targets.level1, y0 / 2u, x0 / 8u + 1u, a1);
    put(targets.level1, y0 / 2u + 1u, x0 / 8u, b0);
    put(targets.level1, y0 / 2u + 1u, x0 / 8u + 1u, b1);
    put(targets.level2, y0 / 4u, x0 / 16u, halve(a0, a1, b0, b1, 1u));
}

// Eight Cb Cr pairs of chroma row `cy` from the frame's column x0 on.
fn chroma_row(cy: u32, x0: u32) -> vec4u {
    let i = at(params.input_planes.x, params.input.w, params.input.y / 2u, cy, x0);
    return vec4u(raw[i], raw[i + 1u], raw[i + 2u], raw[i + 3u]);
}
