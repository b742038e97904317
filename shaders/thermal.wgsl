// A thermal frame's counts to colours: each count's level from the gain table, the level's
// colour from the palette. The CPU reference is `thermal::colourise` (src/thermal/mod.rs);
// `thermal_bin` is the twin of `GainTable::bin` (src/thermal/gain.rs).

const BINS: u32 = 1024u;

// The gain table's range and the frame's size: twin of the Rust `ThermalParams`
// (src/render/gpu/thermal.rs).
struct ThermalParams {
    lo: u32,
    span: u32,
    width: u32,
    height: u32,
}

@group(0) @binding(0) var<uniform> thermal: ThermalParams;
// A level (0..=255) for each of the BINS bins.
@group(0) @binding(1) var<storage, read> levels: array<u32>;
// 256 colours, RGBA bytes in a word (R the low byte).
@group(0) @binding(2) var<storage, read> palette: array<u32>;
// The frame's counts, two a word (the first in the low half), rows top to bottom.
@group(0) @binding(3) var<storage, read> counts: array<u32>;
// The colours out, a word a pixel.
@group(0) @binding(4) var<storage, read_write> colours: array<u32>;

// The bin of count `c`: counts below the range in the first, above it in the last.
fn thermal_bin(c: u32) -> u32 {
    let d = min(c - min(c, thermal.lo), thermal.span - 1u);
    return d * BINS / thermal.span;
}

fn thermal_colour(c: u32) -> u32 {
    return palette[levels[thermal_bin(c)]];
}

@compute @workgroup_size(8, 8)
fn colourise(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= thermal.width || id.y >= thermal.height {
        return;
    }
    let i = id.y * thermal.width + id.x;
    let word = counts[i / 2u];
    let c = select(word & 0xffffu, word >> 16u, (i & 1u) == 1u);
    colours[i] = thermal_colour(c);
}
