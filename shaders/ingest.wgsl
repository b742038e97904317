// Upload, second half: the raw camera bytes (RGBA8, I420 or NV12, as one array of words) become
// mip levels 0 and 1 of the source texture. One invocation per 2x2 block, which in 4:2:0
// shares one chroma sample, so each byte is read once. The format is the INPUT_FORMAT override.
// Only the lens's imaged box is converted (dispatched over it, from its origin); the texture
// stays black around it.

override INPUT_FORMAT: u32 = 0u;

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> raw: array<u32>;
@group(0) @binding(2) var level0: texture_storage_2d<rgba8unorm, write>;
@group(0) @binding(3) var level1: texture_storage_2d<rgba8unorm, write>;

fn byte_at(i: u32) -> f32 {
    return f32((raw[i >> 2u] >> ((i & 3u) * 8u)) & 0xffu);
}

fn fetch(x: u32, y: u32, u: f32, v: f32) -> vec3f {
    if INPUT_FORMAT == FORMAT_RGBA {
        return unpack4x8unorm(raw[(y * params.input.z) / 4u + x]).rgb;
    }
    return yuv_to_rgb(byte_at(y * params.input.z + x), u, v);
}

@compute @workgroup_size(8, 8)
fn ingest(@builtin(global_invocation_id) gid: vec3u) {
    let size = params.input.xy;
    let origin = vec2u(params.input_planes.w & 0xffffu, params.input_planes.w >> 16u);
    let block = gid.xy + origin / 2u;
    let x0 = block.x * 2u;
    let y0 = block.y * 2u;
    if x0 >= size.x || y0 >= size.y {
        return;
    }
    // The block's chroma sample (unused for RGBA).
    var u = 128.0;
    var v = 128.0;
    let row = (y0 / 2u) * params.input.w;
    if INPUT_FORMAT == FORMAT_I420 {
        u = byte_at(params.input_planes.x + row + x0 / 2u);
        v = byte_at(params.input_planes.y + row + x0 / 2u);
    } else if INPUT_FORMAT == FORMAT_NV12 {
        u = byte_at(params.input_planes.x + row + x0);
        v = byte_at(params.input_planes.x + row + x0 + 1u);
    }
    var sum = vec3f(0.0);
    for (var i = 0u; i < 4u; i++) {
        let x = x0 + (i & 1u);
        let y = y0 + (i >> 1u);
        if x < size.x && y < size.y {
            // Quantized as the texture stores it, so level 1 averages what level 0 holds.
            let c = round(fetch(x, y, u, v) * 255.0) / 255.0;
            textureStore(level0, vec2u(x, y), vec4f(c, 1.0));
            sum += c;
        }
    }
    if all(block < textureDimensions(level1)) {
        textureStore(level1, block, vec4f(sum * 0.25, 1.0));
    }
}
