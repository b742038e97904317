// The rest of the source's mip chain: level k + 1 is the 2x2 box average of level k (the last
// row or column of an odd level is dropped, as the texture's own level sizes do).

@group(0) @binding(0) var finer: texture_2d<f32>;
@group(0) @binding(1) var coarser: texture_storage_2d<rgba8unorm, write>;

@compute @workgroup_size(8, 8)
fn downsample(@builtin(global_invocation_id) gid: vec3u) {
    if any(gid.xy >= textureDimensions(coarser)) {
        return;
    }
    let p = gid.xy * 2u;
    let c = textureLoad(finer, p, 0) + textureLoad(finer, p + vec2u(1u, 0u), 0)
        + textureLoad(finer, p + vec2u(0u, 1u), 0) + textureLoad(finer, p + vec2u(1u, 1u), 0);
    textureStore(coarser, gid.xy, vec4f(c.rgb * 0.25, 1.0));
}
