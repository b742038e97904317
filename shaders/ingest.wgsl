// Upload, second half: the raw camera bytes (RGBA8, I420 or NV12, as one array of words) become
// mip levels 0, 1 and 2 of the source texture. One invocation per 4x4 block: it reads each
// row's four luma bytes as one word and each 2x2's chroma sample once, stores 16 texels of
// level 0, the 4 of level 1 they average to and the 1 of level 2 those average to (each
// level averages what the level below holds, quantized as the texture stores it). The format
// is the INPUT_FORMAT override. Only the lens's imaged box is converted (dispatched over it,
// from its origin); the texture stays black around it.

override INPUT_FORMAT: u32 = 0u;

@group(0) @binding(0) var<uniform> params: Params;
// The frame's bytes, padded by 16 so that reading a row's last block never leaves the buffer.
@group(0) @binding(1) var<storage, read> raw: array<u32>;
@group(0) @binding(2) var level0: texture_storage_2d<rgba8unorm, write>;
@group(0) @binding(3) var level1: texture_storage_2d<rgba8unorm, write>;
@group(0) @binding(4) var level2: texture_storage_2d<rgba8unorm, write>;

// The four bytes from byte `i` on, any alignment, as code values 0..255.
fn bytes4(i: u32) -> vec4f {
    let shift = (i & 3u) * 8u;
    let lo = raw[i >> 2u];
    let hi = raw[(i >> 2u) + 1u];
    let w = select((lo >> shift) | (hi << (32u - shift)), lo, shift == 0u);
    return vec4f(f32(w & 0xffu), f32((w >> 8u) & 0xffu), f32((w >> 16u) & 0xffu), f32(w >> 24u));
}

// As the texture stores it, so each level averages what the one below holds; halves round
// up, as src/render/mip.rs rounds its averages.
fn stored(c: vec3f) -> vec3f {
    return floor(c * 255.0 + 0.5) / 255.0;
}

// Four pixels of a row, left to right.
struct Row4 {
    c0: vec3f,
    c1: vec3f,
    c2: vec3f,
    c3: vec3f,
}

// Pixels x0..x0+3 of row y (x0 a multiple of 4), as stored. Past the frame's right edge the
// values are whatever the bytes hold; they are never stored.
fn row4(x0: u32, y: u32) -> Row4 {
    if INPUT_FORMAT == FORMAT_RGBA {
        let i = (y * params.input.z) / 4u + x0;
        return Row4(
            stored(unpack4x8unorm(raw[i]).rgb),
            stored(unpack4x8unorm(raw[i + 1u]).rgb),
            stored(unpack4x8unorm(raw[i + 2u]).rgb),
            stored(unpack4x8unorm(raw[i + 3u]).rgb),
        );
    }
    let luma = bytes4(y * params.input.z + x0);
    let row = (y / 2u) * params.input.w;
    // The two 2x2 blocks' chroma: u0, v0 (pixels x0, x0 + 1), u1, v1 (x0 + 2, x0 + 3).
    var uv = bytes4(params.input_planes.x + row + x0);
    if INPUT_FORMAT == FORMAT_I420 {
        let u = bytes4(params.input_planes.x + row + x0 / 2u);
        let v = bytes4(params.input_planes.y + row + x0 / 2u);
        uv = vec4f(u.x, v.x, u.y, v.y);
    }
    return Row4(
        stored(yuv_to_rgb(luma.x, uv.x, uv.y)),
        stored(yuv_to_rgb(luma.y, uv.x, uv.y)),
        stored(yuv_to_rgb(luma.z, uv.z, uv.w)),
        stored(yuv_to_rgb(luma.w, uv.z, uv.w)),
    );
}

fn store0(x: u32, y: u32, c: vec3f) {
    if x < params.input.x && y < params.input.y {
        textureStore(level0, vec2u(x, y), vec4f(c, 1.0));
    }
}

fn store1(t: vec2u, c: vec3f) {
    if all(t < textureDimensions(level1)) {
        textureStore(level1, t, vec4f(c, 1.0));
    }
}

// Two level-1 texels, left and right.
struct Pair {
    a: vec3f,
    b: vec3f,
}

// Rows y and y + 1 of the block at x0: stores their 8 level-0 texels and the 2 level-1
// texels (at t and t + (1, 0)) they make, and returns those as stored.
fn two_rows(x0: u32, y: u32, t: vec2u) -> Pair {
    // Rows past the frame's bottom edge read its last row instead (never stored).
    let last = params.input.y - 1u;
    let top = row4(x0, min(y, last));
    let bottom = row4(x0, min(y + 1u, last));
    store0(x0, y, top.c0);
    store0(x0 + 1u, y, top.c1);
    store0(x0 + 2u, y, top.c2);
    store0(x0 + 3u, y, top.c3);
    store0(x0, y + 1u, bottom.c0);
    store0(x0 + 1u, y + 1u, bottom.c1);
    store0(x0 + 2u, y + 1u, bottom.c2);
    store0(x0 + 3u, y + 1u, bottom.c3);
    let a = stored((top.c0 + top.c1 + bottom.c0 + bottom.c1) * 0.25);
    let b = stored((top.c2 + top.c3 + bottom.c2 + bottom.c3) * 0.25);
    store1(t, a);
    store1(t + vec2u(1u, 0u), b);
    return Pair(a, b);
}

@compute @workgroup_size(8, 8)
fn ingest(@builtin(global_invocation_id) gid: vec3u) {
    let origin = vec2u(params.input_planes.w & 0xffffu, params.input_planes.w >> 16u);
    let block = gid.xy + origin / 4u;
    let x0 = block.x * 4u;
    let y0 = block.y * 4u;
    if x0 >= params.input.x || y0 >= params.input.y {
        return;
    }
    let upper = two_rows(x0, y0, block * 2u);
    let lower = two_rows(x0, y0 + 2u, block * 2u + vec2u(0u, 1u));
    if all(block < textureDimensions(level2)) {
        let c = (upper.a + upper.b + lower.a + lower.b) * 0.25;
        textureStore(level2, block, vec4f(c, 1.0));
    }
}
