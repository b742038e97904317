// The rest of each plane's mip chain, in the level buffer: level k + 1 from level k, one word
// of the coarser level per invocation, each byte the rounded mean of its channel in the 2x2
// texels under it (the last row or column of an odd level is dropped, as the textures' own
// level sizes do). The renderer copies every level into its plane's texture afterwards.

// One level from the one before; twin of the Rust `MipStep` (src/render/gpu/planes/mod.rs).
struct Step {
    finer: Region,
    coarser: Region,
    // Bytes per texel: 1, 2 or 4.
    channels: vec4u,
}

@group(0) @binding(0) var<storage, read_write> levels: array<u32>;
@group(0) @binding(1) var<uniform> step: Step;

@compute @workgroup_size(8, 8)
fn downsample(@builtin(global_invocation_id) gid: vec3u) {
    let ch = step.channels.x;
    let c = step.coarser;
    if gid.x * 4u >= c.width * ch || gid.y >= c.height {
        return;
    }
    let f = step.finer;
    let top = (f.offset + 2u * gid.y * f.stride) / 4u + 2u * gid.x;
    let bottom = top + f.stride / 4u;
    let out = halve(levels[top], levels[top + 1u], levels[bottom], levels[bottom + 1u], ch);
    levels[(c.offset + gid.y * c.stride) / 4u + gid.x] = out;
}
