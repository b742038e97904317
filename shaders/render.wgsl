// The frame pass: every view and detection tile of the output frame, from the source's mip
// chain. One invocation draws an 8x2 block (four 2x2 quads), which is what I420 and NV12 need
// to write whole words of every plane. `draw` covers the frame and draws each block that lies
// in one view (or none) with that view, named by the block table (src/render/gpu/blocks.rs),
// projecting each of its rows at four pixels where a parabola through them fits the rest
// (`run_of`, shaders/views.wgsl); `draw_mixed` draws the listed blocks that straddle a
// view's or the frame's edge, finding and projecting each pixel's view. Per frame only `params` and `views` change
// (`blocks` when the rectangles do); the input and output formats, the filter and the view
// kinds present are overrides fixed with the pipeline.
//
// Filtering, as src/render/cpu.rs and src/render/mip.rs do it: a trilinear sample whose level
// of detail is log2 of the larger fisheye-pixel step to the pixel's quad neighbours (x ^ 1,
// y ^ 1), the derivatives a fragment shader would take. Each plane of the source has its own
// texture and chain (src/render/gpu/planes/mod.rs): RGBA; or luma, and Cb Cr pairs from half
// size, filtered in Y Cb Cr and converted afterwards (for 4:2:0 output, not at all: `yuv_through`).
// For 4:2:0 output, 4:2:0 chroma is sampled once per 2x2 quad of the output (per view in a
// quad that straddles views), as the output keeps it; for RGBA output, once per pixel.

const FILTER_MIP: u32 = 0u;
const FILTER_BILINEAR: u32 = 1u;

override INPUT_FORMAT: u32 = 0u;
override OUTPUT_FORMAT: u32 = 0u;
override FILTER: u32 = 0u;

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<uniform> views: array<View, MAX_VIEWS>;
// RGBA, or luma.
@group(0) @binding(2) var plane0: texture_2d<f32>;
@group(0) @binding(3) var trilinear: sampler;
@group(0) @binding(4) var<storage, read_write> out: array<u32>;
// The block table (one word per 8x2 block, row by row: a view index, NO_VIEW or MIXED), then
// the MIXED blocks' coordinates (bx | by << 16), params.output_planes.w of them.
@group(0) @binding(5) var<storage, read> blocks: array<u32>;
// Chroma (Cb Cr), for 4:2:0 input.
@group(0) @binding(6) var plane1: texture_2d<f32>;

// A block the per-pixel dispatch draws (`MIXED` in src/render/gpu/blocks.rs).
const MIXED: u32 = 0xfffffffeu;

// A pixel's level of detail, from where it lands (`q`) and where its quad neighbours in x and
// y land. A neighbour drawn by another view, or black, or in the other image of a lens pair,
// does not count (src/render/cpu.rs measures the same way).
fn lod_of(q: vec3f, qx: vec3f, x_same: bool, qy: vec3f, y_same: bool) -> f32 {
    if FILTER == FILTER_BILINEAR {
        return 0.0;
    }
    let sx = select(0.0, distance(qx.xy, q.xy), x_same && qx.z > 0.0 && same_image(q.xy, qx.xy));
    let sy = select(0.0, distance(qy.xy, q.xy), y_same && qy.z > 0.0 && same_image(q.xy, qy.xy));
    return clamp(log2(max(max(sx, sy), 1.0)), 0.0, f32(params.input_planes.z - 1u));
}

// Fisheye pixel coordinates → texture coordinates. Divisions are dear on a CPU; the one
// reciprocal here is worked out once per invocation, however many samples it serves.
fn uv_of(q: vec2f) -> vec2f {
    return (q + 0.5) * (1.0 / params.lens.offset_frame.zw);
}

// 4:2:0 input's chroma (Cb Cr, 0..1) at fisheye point q, level of detail `lod` counted in
// the chroma's own chain (whose level 0 is the frame's level 1). Not sampled where nothing
// `seen` is there: such pixels are black whatever their chroma (`colour`).
fn chroma_at(q: vec2f, lod: f32, seen: bool) -> vec2f {
    var cbcr = vec2f(0.5);
    if seen {
        cbcr = textureSampleLevel(plane1, trilinear, uv_of(q), lod).rg;
    }
    return cbcr;
}

// A pixel's own chroma, for RGBA output: at the pixel, one level up.
fn pixel_chroma(q: vec3f, lod: f32) -> vec2f {
    return chroma_at(q.xy, max(lod - 1.0, 0.0), q.z > 0.0);
}

// For 4:2:0 output, the chroma a group of a quad's pixels share (4:2:0 output keeps one per
// quad): one sample at the mean of where they land, at the largest of their levels of detail
// (a quad spans two pixels each way, as a chroma texel spans two of the frame's, so a pixel's
// level of detail is the chroma chain's own). The group is pixel a and those of b, c, d whose
// flag is set; pixels that see nothing do not count.
fn group_chroma(
    a: vec3f, la: f32,
    b: vec3f, lb: f32, b_in: bool,
    c: vec3f, lc: f32, c_in: bool,
    d: vec3f, ld: f32, d_in: bool,
) -> vec2f {
    let ia = a.z > 0.0;
    let ib = b_in && b.z > 0.0;
    let ic = c_in && c.z > 0.0;
    let id = d_in && d.z > 0.0;
    let zero = vec2f(0.0);
    let sum = select(zero, a.xy, ia) + select(zero, b.xy, ib) + select(zero, c.xy, ic)
        + select(zero, d.xy, id);
    let n = select(0.0, 1.0, ia) + select(0.0, 1.0, ib) + select(0.0, 1.0, ic)
        + select(0.0, 1.0, id);
    let lod = max(
        max(select(0.0, la, ia), select(0.0, lb, ib)),
        max(select(0.0, lc, ic), select(0.0, ld, id)),
    );
    return chroma_at(sum * (1.0 / max(n, 1.0)), lod, n > 0.0);
}

// Whether 4:2:0 input reaches 4:2:0 output as it is: the pixels' colours are then Y Cb Cr
// code values (0..1), never RGB. A round trip through RGB would cost a conversion each way
// per pixel and clip the camera's colours that RGB cannot hold.
fn yuv_through() -> bool {
    return INPUT_FORMAT != FORMAT_RGBA && OUTPUT_FORMAT != FORMAT_RGBA;
}

// Black as Y Cb Cr code values, what `rgb_to_yuv` makes of RGB black.
const BLACK_YUV: vec3f = vec3f(16.0, 128.0, 128.0) / 255.0;

// Black in the colours pixels are drawn in.
fn black() -> vec3f {
    return select(vec3f(0.0), BLACK_YUV, yuv_through());
}

// The colour of a pixel that lands at `q` with level of detail `lod`: RGBA, or luma at the
// pixel with its group's chroma `cbcr` for 4:2:0 input (as Y Cb Cr where `yuv_through`).
fn colour(q: vec3f, lod: f32, cbcr: vec2f) -> vec3f {
    // Outside the image circle nothing is sampled. A branch that no lane of a SIMD group
    // takes costs nothing on Mesa 25's llvmpipe (on 22.3 both sides always ran), and views
    // that reach past the circle have many such groups.
    var first = vec4f(0.0);
    if q.z > 0.0 {
        first = textureSampleLevel(plane0, trilinear, uv_of(q.xy), lod);
    }
    if yuv_through() {
        return select(black(), vec3f(first.r, cbcr), q.z > 0.0);
    }
    var c = first.rgb;
    if INPUT_FORMAT != FORMAT_RGBA {
        c = yuv_to_rgb(first.r * 255.0, cbcr.x * 255.0, cbcr.y * 255.0);
    }
    return select(vec3f(0.0), c, q.z > 0.0);
}

// A 2x2 quad's colours: (x0, y0), (x0+1, y0), (x0, y0+1), (x0+1, y0+1).
struct Quad {
    c0: vec3f,
    c1: vec3f,
    c2: vec3f,
    c3: vec3f,
}

// A quad whose pixels may belong to different views (or none); for 4:2:0 in and out, each
// view's pixels share their chroma.
fn draw_quad(x0: u32, y0: u32) -> Quad {
    let x1 = x0 + 1u;
    let y1 = y0 + 1u;
    let v0 = view_at(x0, y0);
    let v1 = view_at(x1, y0);
    let v2 = view_at(x0, y1);
    let v3 = view_at(x1, y1);
    let q0 = view_pixel(v0, x0, y0);
    let q1 = view_pixel(v1, x1, y0);
    let q2 = view_pixel(v2, x0, y1);
    let q3 = view_pixel(v3, x1, y1);
    let l0 = lod_of(q0, q1, v1 == v0, q2, v2 == v0);
    let l1 = lod_of(q1, q0, v0 == v1, q3, v3 == v1);
    let l2 = lod_of(q2, q3, v3 == v2, q0, v0 == v2);
    let l3 = lod_of(q3, q2, v2 == v3, q1, v1 == v3);
    var c0 = vec2f(0.5);
    var c1 = c0;
    var c2 = c0;
    var c3 = c0;
    if INPUT_FORMAT != FORMAT_RGBA && OUTPUT_FORMAT == FORMAT_RGBA {
        c0 = pixel_chroma(q0, l0);
        c1 = pixel_chroma(q1, l1);
        c2 = pixel_chroma(q2, l2);
        c3 = pixel_chroma(q3, l3);
    } else if INPUT_FORMAT != FORMAT_RGBA {
        c0 = group_chroma(q0, l0, q1, l1, v1 == v0, q2, l2, v2 == v0, q3, l3, v3 == v0);
        c1 = group_chroma(q1, l1, q0, l0, v0 == v1, q2, l2, v2 == v1, q3, l3, v3 == v1);
        c2 = group_chroma(q2, l2, q0, l0, v0 == v2, q1, l1, v1 == v2, q3, l3, v3 == v2);
        c3 = group_chroma(q3, l3, q0, l0, v0 == v3, q1, l1, v1 == v3, q2, l2, v2 == v3);
    }
    return Quad(colour(q0, l0, c0), colour(q1, l1, c1), colour(q2, l2, c2), colour(q3, l3, c3));
}

// A quad that lies in one view, its pixels landing at q0 (x0, y0), q1 (x0+1, y0), q2 (x0,
// y0+1) and q3 (x0+1, y0+1).
fn quad_of(q0: vec3f, q1: vec3f, q2: vec3f, q3: vec3f) -> Quad {
    let l0 = lod_of(q0, q1, true, q2, true);
    let l1 = lod_of(q1, q0, true, q3, true);
    let l2 = lod_of(q2, q3, true, q0, true);
    let l3 = lod_of(q3, q2, true, q1, true);
    if INPUT_FORMAT != FORMAT_RGBA && OUTPUT_FORMAT == FORMAT_RGBA {
        return Quad(
            colour(q0, l0, pixel_chroma(q0, l0)),
            colour(q1, l1, pixel_chroma(q1, l1)),
            colour(q2, l2, pixel_chroma(q2, l2)),
            colour(q3, l3, pixel_chroma(q3, l3)),
        );
    }
    var cbcr = vec2f(0.5);
    if INPUT_FORMAT != FORMAT_RGBA {
        cbcr = group_chroma(q0, l0, q1, l1, true, q2, l2, true, q3, l3, true);
    }
    return Quad(colour(q0, l0, cbcr), colour(q1, l1, cbcr), colour(q2, l2, cbcr), colour(q3, l3, cbcr));
}

fn luma(c: vec3f) -> f32 {
    if yuv_through() {
        return c.x;
    }
    return rgb_to_yuv(c).x;
}

// A quad's mean colour's chroma (the conversion is affine: the mean of the pixels' chroma).
fn chroma(q: Quad) -> vec2f {
    let mean = (q.c0 + q.c1 + q.c2 + q.c3) * 0.25;
    if yuv_through() {
        return mean.yz;
    }
    return rgb_to_yuv(mean).yz;
}

// pack4x8unorm written out, the same value for every number: llvmpipe converts the builtin's
// floats to integers lane by lane (a fifth of the draw's instructions went there), these
// stay in vectors. n + 2^23 holds the integer n in its low mantissa bits.
fn pack_unorm(v: vec4f) -> u32 {
    let n = floor(clamp(v, vec4f(0.0), vec4f(1.0)) * 255.0 + 0.5);
    let b = bitcast<vec4u>(n + 8388608.0) & vec4u(0xffu);
    return b.x | (b.y << 8u) | (b.z << 16u) | (b.w << 24u);
}

fn store_rgba(x: u32, y: u32, c: vec3f) {
    if x < params.output.x && y < params.output.y {
        out[(y * params.output.w) / 4u + x] = pack_unorm(vec4f(c, 1.0));
    }
}

fn store_quad_rgba(x0: u32, y0: u32, q: Quad) {
    store_rgba(x0, y0, q.c0);
    store_rgba(x0 + 1u, y0, q.c1);
    store_rgba(x0, y0 + 1u, q.c2);
    store_rgba(x0 + 1u, y0 + 1u, q.c3);
}

// Blocks across the frame.
fn blocks_across() -> u32 {
    return (params.output.x + 7u) / 8u;
}

@compute @workgroup_size(8, 8)
fn draw(@builtin(global_invocation_id) gid: vec3u) {
    let bx = gid.x * 8u;
    let by = gid.y * 2u;
    if bx >= params.output.x || by >= params.output.y {
        return;
    }
    let entry = blocks[gid.y * blocks_across() + gid.x];
    if entry == MIXED {
        return;
    }
    let vi = bitcast<i32>(entry);
    // A block in no view is black; skipping its projection costs nothing where the SIMD
    // group's blocks agree (Mesa 25's llvmpipe branches; 22.3 ran both sides anyway).
    if vi == NO_VIEW {
        let k = black();
        let empty = Quad(k, k, k, k);
        store_block(bx, by, empty, empty, empty, empty);
        return;
    }
    // One view for the whole block, fetched once.
    let v = views[vi];
    let p = view_xy(v, bx, by);
    let s = block_shutter(v, p);
    let below = p + vec2f(0.0, 1.0);
    let a = run_of(v, p, s, s.first);
    let b = run_of(v, below, s, view_point_in(v, below, s));
    store_block(
        bx,
        by,
        quad_of(a.c0, a.c1, b.c0, b.c1),
        quad_of(a.c2, a.c3, b.c2, b.c3),
        quad_of(a.c4, a.c5, b.c4, b.c5),
        quad_of(a.c6, a.c7, b.c6, b.c7),
    );
}

@compute @workgroup_size(64)
fn draw_mixed(@builtin(global_invocation_id) gid: vec3u) {
    if gid.x >= params.output_planes.w {
        return;
    }
    let b = blocks[blocks_across() * ((params.output.y + 1u) / 2u) + gid.x];
    let bx = (b & 0xffffu) * 8u;
    let by = (b >> 16u) * 2u;
    store_block(
        bx,
        by,
        draw_quad(bx, by),
        draw_quad(bx + 2u, by),
        draw_quad(bx + 4u, by),
        draw_quad(bx + 6u, by),
    );
}

// Writes the block's four quads (left to right) in the output format.
fn store_block(bx: u32, by: u32, a: Quad, b: Quad, c: Quad, d: Quad) {
    if OUTPUT_FORMAT == FORMAT_RGBA {
        store_quad_rgba(bx, by, a);
        store_quad_rgba(bx + 2u, by, b);
        store_quad_rgba(bx + 4u, by, c);
        store_quad_rgba(bx + 6u, by, d);
        return;
    }
    // Luma: two rows of two words; the padded stride keeps every word inside the plane.
    let stride = params.output.w;
    let top = (by * stride + bx) / 4u;
    let bottom = ((by + 1u) * stride + bx) / 4u;
    out[top] = pack_unorm(vec4f(luma(a.c0), luma(a.c1), luma(b.c0), luma(b.c1)));
    out[top + 1u] = pack_unorm(vec4f(luma(c.c0), luma(c.c1), luma(d.c0), luma(d.c1)));
    out[bottom] = pack_unorm(vec4f(luma(a.c2), luma(a.c3), luma(b.c2), luma(b.c3)));
    out[bottom + 1u] = pack_unorm(vec4f(luma(c.c2), luma(c.c3), luma(d.c2), luma(d.c3)));
    // Chroma: each quad's mean colour.
    let ua = chroma(a);
    let ub = chroma(b);
    let uc = chroma(c);
    let ud = chroma(d);
    let row = params.output_planes.x + (by / 2u) * params.output_planes.z;
    if OUTPUT_FORMAT == FORMAT_I420 {
        let v_row = params.output_planes.y + (by / 2u) * params.output_planes.z;
        out[(row + bx / 2u) / 4u] = pack_unorm(vec4f(ua.x, ub.x, uc.x, ud.x));
        out[(v_row + bx / 2u) / 4u] = pack_unorm(vec4f(ua.y, ub.y, uc.y, ud.y));
    } else {
        let w = (row + bx) / 4u;
        out[w] = pack_unorm(vec4f(ua, ub));
        out[w + 1u] = pack_unorm(vec4f(uc, ud));
    }
}
