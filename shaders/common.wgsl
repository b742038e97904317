// What every pass shares: the per-frame parameters (one small uniform buffer, rewritten each
// frame) and BT.709 limited-range colour conversion, the twin of src/frame/yuv.rs.
//
// Prepended to each pass's source (after lens.wgsl) by src/render/gpu/shaders.rs. Every
// constant and struct a pass shares with the Rust side is held to its Rust twin by
// src/render/gpu/twins.rs.

const FORMAT_RGBA: u32 = 0u;
const FORMAT_I420: u32 = 1u;
const FORMAT_NV12: u32 = 2u;

// Twin of the Rust `GpuParams` (src/render/gpu/params.rs).
struct Params {
    // Output width, height, number of views, luma (or RGBA) row stride in bytes.
    output: vec4u,
    // Output chroma: U (or UV) plane offset, V plane offset, chroma row stride, all in bytes;
    // then the number of blocks the draw pass's per-pixel dispatch draws (render.wgsl).
    output_planes: vec4u,
    // Input width, height, luma (or RGBA) row stride, chroma row stride (bytes).
    input: vec4u,
    // Input chroma plane offsets (U or UV, V) in bytes, mip levels, unused.
    input_planes: vec4u,
    lens: Lens,
    // The rolling shutter (the frame's `ShutterTable`, src/geometry/shutter.rs): a fisheye
    // point's knot coordinate is dot(xyz, (x, y, 1)); w is 1 where the frame has a table.
    shutter_line: vec4f,
    // Rotations (quaternions x, y, z, w) from the lens frame at the middle row to the lens
    // frame when each knot's row was read.
    shutter: array<vec4f, KNOTS>,
}

// A rectangle of the output and how its pixels map to rays: twin of the Rust `GpuView`
// (src/render/gpu/params.rs). The draw pass's views (views.wgsl), the thermal layer's entries.
struct View {
    // x, y, w, h in output pixels.
    rect: vec4u,
    // KIND_*, unused ×3.
    kind: vec4u,
    // lens_from_view, by columns (xyz).
    m0: vec4f,
    m1: vec4f,
    m2: vec4f,
    // Rectilinear: focal, w/2, h/2. Panorama: radians per pixel, pitch, w/2, h/2.
    // Fisheye: origin x, y, fisheye pixels per view pixel.
    p: vec4f,
}

// Whether rectangle r (x, y, w, h) holds pixel (x, y).
fn contains(r: vec4u, x: u32, y: u32) -> bool {
    return x >= r.x && y >= r.y && x < r.x + r.z && y < r.y + r.w;
}

// KNOTS in src/geometry/shutter.rs.
const KNOTS: u32 = 17u;

const KR: f32 = 0.2126;
const KB: f32 = 0.0722;
const KG: f32 = 0.7152;

// RGB in [0, 1] → (Y, Cb, Cr) as 8-bit code values in [0, 1] (limited range: Y 16..235,
// chroma 16..240).
fn rgb_to_yuv(c: vec3f) -> vec3f {
    let y = dot(c, vec3f(KR, KG, KB));
    let cb = (c.b - y) * (0.5 / (1.0 - KB));
    let cr = (c.r - y) * (0.5 / (1.0 - KR));
    return vec3f(16.0 + 219.0 * y, 128.0 + 224.0 * cb, 128.0 + 224.0 * cr) * (1.0 / 255.0);
}

// 8-bit code values (0..255) → RGB in [0, 1].
fn yuv_to_rgb(y8: f32, u8: f32, v8: f32) -> vec3f {
    let y = (y8 - 16.0) * (1.0 / 219.0);
    let cb = (u8 - 128.0) * (1.0 / 224.0);
    let cr = (v8 - 128.0) * (1.0 / 224.0);
    let r = y + 2.0 * (1.0 - KR) * cr;
    let b = y + 2.0 * (1.0 - KB) * cb;
    let g = (y - KR * r - KB * b) * (1.0 / KG);
    return clamp(vec3f(r, g, b), vec3f(0.0), vec3f(1.0));
}
