// The thermal layer: the thermal camera's colours (from the colouring pass, shaders/thermal.wgsl)
// drawn over the output frame the draw pass wrote, in place. Each entry is a rectangle of the
// output whose pixels look along rays turned into the thermal lens frame; a pixel the thermal
// lens images takes the thermal colour (bilinear between thermal pixels) at the entry's
// share, one it does not is black or left alone. The twin of `ThermalLayer::draw_rgb`
// (src/render/thermal_layer.rs), which mixes in RGB; for 4:2:0 output the luma is mixed pixel
// by pixel and each quad's chroma by the mean of its pixels' shares, the same where the
// shares agree (the conversion is affine).
//
// One invocation owns an 8x2 block, as the draw pass does, so every word of every plane it
// rewrites is its own. Prepended with the lens library (the thermal lens, LENS_MODEL its
// model) and the common definitions by src/render/gpu/shaders.rs.

override OUTPUT_FORMAT: u32 = 0u;

// MAX_ENTRIES in src/render/gpu/layer.rs.
const MAX_ENTRIES: u32 = 16u;
// KIND_PANORAMA in src/render/gpu/params.rs (views.wgsl's).
const LAYER_PANORAMA: u32 = 2u;

// Twin of the Rust `GpuLayerParams` (src/render/gpu/layer.rs).
struct LayerParams {
    // Output width, height, number of entries, luma (or RGBA) row stride in bytes.
    output: vec4u,
    // Output chroma: U (or UV) plane offset, V plane offset, chroma row stride (bytes); unused.
    output_planes: vec4u,
    // The thermal picture's width and height; unused ×2.
    picture: vec4u,
    lens: Lens,
}

// Twin of the Rust `GpuLayerEntry`: the rectangle and its rays as a view's (`kind.y` 1 where
// unseen pixels are black; `m` turns view rays into the thermal lens frame), and the thermal
// colour's share (x; unused ×3).
struct Entry {
    view: View,
    share: vec4f,
}

@group(0) @binding(0) var<uniform> params: LayerParams;
@group(0) @binding(1) var<uniform> entries: array<Entry, MAX_ENTRIES>;
// The thermal colours, a word a pixel (R the low byte), rows top to bottom.
@group(0) @binding(2) var<storage, read> colours: array<u32>;
@group(0) @binding(3) var<storage, read_write> out: array<u32>;

// Whether any entry reaches into the 8x2 block at (bx, by).
fn block_covered(bx: u32, by: u32) -> bool {
    for (var i = 0u; i < params.output.z; i++) {
        let r = entries[i].view.rect;
        if bx < r.x + r.z && r.x < bx + 8u && by < r.y + r.w && r.y < by + 2u {
            return true;
        }
    }
    return false;
}

// Thermal pixel (x, y), its edges held beyond the edge.
fn texel(x: f32, y: f32) -> vec3f {
    let w = i32(params.picture.x);
    let h = i32(params.picture.y);
    let xi = clamp(i32(x), 0, w - 1);
    let yi = clamp(i32(y), 0, h - 1);
    return unpack4x8unorm(colours[u32(yi * w + xi)]).rgb;
}

// The thermal colour at OpenCV point q, bilinear (`thermal_layer::sample`).
fn picture_at(q: vec2f) -> vec3f {
    let f0 = floor(q);
    let f = q - f0;
    let top = mix(texel(f0.x, f0.y), texel(f0.x + 1.0, f0.y), f.x);
    let bottom = mix(texel(f0.x, f0.y + 1.0), texel(f0.x + 1.0, f0.y + 1.0), f.x);
    return mix(top, bottom, f.y);
}

// The thermal colour over output pixel (x, y) (rgb, as 0..1) and its share (w): share 0 where
// no entry holds the pixel, or the thermal lens does not see it and the entry leaves it.
fn layer_at(x: u32, y: u32) -> vec4f {
    if x >= params.output.x || y >= params.output.y {
        return vec4f(0.0);
    }
    var ei = -1;
    for (var i = i32(params.output.z) - 1; i >= 0; i--) {
        if contains(entries[i].view.rect, x, y) {
            ei = i;
            break;
        }
    }
    if ei < 0 {
        return vec4f(0.0);
    }
    let e = entries[ei].view;
    let p = vec2f(f32(x - e.rect.x), f32(y - e.rect.y)) + 0.5;
    let k = e.p;
    let a = (p.x - k.z) * k.x;
    let el = k.y - (p.y - k.w) * k.x;
    let panorama = vec3f(cos(el) * cos(a), cos(el) * sin(a), -sin(el));
    let rectilinear = vec3f(k.x, p.x - k.y, p.y - k.z);
    let ray = select(rectilinear, panorama, e.kind.x == LAYER_PANORAMA);
    let m = mat3x3f(e.m0.xyz, e.m1.xyz, e.m2.xyz);
    let q = lens_project(m * ray);
    if q.z > 0.0 {
        return vec4f(picture_at(q.xy), entries[ei].share.x);
    }
    return select(vec4f(0.0), vec4f(0.0, 0.0, 0.0, 1.0), e.kind.y == 1u);
}

// A word of four 8-bit values (0..1) with each mixed towards its thermal value by its share.
fn mix_word(word: u32, a: vec4f, b: vec4f, c: vec4f, d: vec4f) -> u32 {
    let v = unpack4x8unorm(word);
    let t = vec4f(rgb_to_yuv(a.rgb).x, rgb_to_yuv(b.rgb).x, rgb_to_yuv(c.rgb).x, rgb_to_yuv(d.rgb).x);
    return pack4x8unorm(mix(v, t, vec4f(a.w, b.w, c.w, d.w)));
}

// A quad's chroma (Cb, Cr as 0..1) moved towards its pixels' thermal chroma by the mean of
// their shares: the mean of the pixels' mixed chroma.
fn mix_chroma(c: vec2f, a: vec4f, b: vec4f, d: vec4f, e: vec4f) -> vec2f {
    let moved = a.w * (rgb_to_yuv(a.rgb).yz - c) + b.w * (rgb_to_yuv(b.rgb).yz - c)
        + d.w * (rgb_to_yuv(d.rgb).yz - c) + e.w * (rgb_to_yuv(e.rgb).yz - c);
    return c + 0.25 * moved;
}

fn mix_rgba(x: u32, y: u32, t: vec4f) {
    if t.w > 0.0 {
        let i = (y * params.output.w) / 4u + x;
        let c = unpack4x8unorm(out[i]).rgb;
        out[i] = pack4x8unorm(vec4f(mix(c, t.rgb, t.w), 1.0));
    }
}

@compute @workgroup_size(8, 8)
fn layer(@builtin(global_invocation_id) gid: vec3u) {
    let bx = gid.x * 8u;
    let by = gid.y * 2u;
    if bx >= params.output.x || by >= params.output.y || !block_covered(bx, by) {
        return;
    }
    if OUTPUT_FORMAT == FORMAT_RGBA {
        for (var i = 0u; i < 8u; i++) {
            mix_rgba(bx + i, by, layer_at(bx + i, by));
            mix_rgba(bx + i, by + 1u, layer_at(bx + i, by + 1u));
        }
        return;
    }
    // The block's 16 pixels, row by row: t0..t7 the top row, b0..b7 the bottom one.
    let t0 = layer_at(bx, by);
    let t1 = layer_at(bx + 1u, by);
    let t2 = layer_at(bx + 2u, by);
    let t3 = layer_at(bx + 3u, by);
    let t4 = layer_at(bx + 4u, by);
    let t5 = layer_at(bx + 5u, by);
    let t6 = layer_at(bx + 6u, by);
    let t7 = layer_at(bx + 7u, by);
    let b0 = layer_at(bx, by + 1u);
    let b1 = layer_at(bx + 1u, by + 1u);
    let b2 = layer_at(bx + 2u, by + 1u);
    let b3 = layer_at(bx + 3u, by + 1u);
    let b4 = layer_at(bx + 4u, by + 1u);
    let b5 = layer_at(bx + 5u, by + 1u);
    let b6 = layer_at(bx + 6u, by + 1u);
    let b7 = layer_at(bx + 7u, by + 1u);
    let stride = params.output.w;
    let top = (by * stride + bx) / 4u;
    let bottom = ((by + 1u) * stride + bx) / 4u;
    out[top] = mix_word(out[top], t0, t1, t2, t3);
    out[top + 1u] = mix_word(out[top + 1u], t4, t5, t6, t7);
    out[bottom] = mix_word(out[bottom], b0, b1, b2, b3);
    out[bottom + 1u] = mix_word(out[bottom + 1u], b4, b5, b6, b7);
    let row = params.output_planes.x + (by / 2u) * params.output_planes.z;
    if OUTPUT_FORMAT == FORMAT_I420 {
        let ui = (row + bx / 2u) / 4u;
        let vi = (params.output_planes.y + (by / 2u) * params.output_planes.z + bx / 2u) / 4u;
        let u = unpack4x8unorm(out[ui]);
        let v = unpack4x8unorm(out[vi]);
        let q0 = mix_chroma(vec2f(u.x, v.x), t0, t1, b0, b1);
        let q1 = mix_chroma(vec2f(u.y, v.y), t2, t3, b2, b3);
        let q2 = mix_chroma(vec2f(u.z, v.z), t4, t5, b4, b5);
        let q3 = mix_chroma(vec2f(u.w, v.w), t6, t7, b6, b7);
        out[ui] = pack4x8unorm(vec4f(q0.x, q1.x, q2.x, q3.x));
        out[vi] = pack4x8unorm(vec4f(q0.y, q1.y, q2.y, q3.y));
    } else {
        let w = (row + bx) / 4u;
        let uv01 = unpack4x8unorm(out[w]);
        let uv23 = unpack4x8unorm(out[w + 1u]);
        let q0 = mix_chroma(uv01.xy, t0, t1, b0, b1);
        let q1 = mix_chroma(uv01.zw, t2, t3, b2, b3);
        let q2 = mix_chroma(uv23.xy, t4, t5, b4, b5);
        let q3 = mix_chroma(uv23.zw, t6, t7, b6, b7);
        out[w] = pack4x8unorm(vec4f(q0, q1));
        out[w + 1u] = pack4x8unorm(vec4f(q2, q3));
    }
}
