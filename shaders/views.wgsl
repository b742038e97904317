// Where an output pixel lands in the fisheye: the views and detection tiles of the frame
// (`View`, one per rectangle, in the `views` uniform the draw pass binds), which view draws a
// pixel, and a view's projection of a pixel to a fisheye point, `FramePlan::fisheye_pixel` of
// src/render/plan.rs in f32. A row of a block lies on a parabola through four of its
// projected pixels wherever that fits the rest (`run_of`). The code of view kinds a frame
// lacks folds away when the pipeline is built (the VIEW_KINDS override).
//
// Prepended to shaders/render.wgsl by src/render/gpu/shaders.rs.

const KIND_BLACK: u32 = 0u;
const KIND_RECTILINEAR: u32 = 1u;
const KIND_PANORAMA: u32 = 2u;
const KIND_FISHEYE: u32 = 3u;

// The bit of VIEW_KINDS that says the frame has a rolling shutter to correct (SHUTTER_BIT in
// src/render/gpu/params.rs).
const SHUTTER_BIT: u32 = 4u;
// SHUTTER_STEPS in src/render/plan.rs.
const SHUTTER_STEPS: u32 = 2u;

// The view kinds the frame has, a bit per KIND_*, and SHUTTER_BIT: code for the kinds (and the
// correction) it lacks is left out.
override VIEW_KINDS: u32 = 0x1fu;

const NO_VIEW: i32 = -1;
// MAX_VIEWS in src/render/gpu/params.rs (src/render/gpu/twins.rs holds them equal).
const MAX_VIEWS: u32 = 68u;

// The view drawn at a pixel: the last one containing it (tiles cover views).
fn view_at(x: u32, y: u32) -> i32 {
    for (var i = i32(params.output.z) - 1; i >= 0; i--) {
        if contains(views[i].rect, x, y) {
            return i;
        }
    }
    return NO_VIEW;
}

// The fisheye pixel seen at point p of view `vi` (xy) and whether anything is imaged (z):
// FramePlan::fisheye_pixel. Written without branches on the view's kind: a software
// rasterizer runs both sides of a branch whenever its lanes disagree, so one lens projection
// serves the rectified kinds and selects pick the result. The code of kinds the frame lacks
// (VIEW_KINDS) folds away when the pipeline is built.
fn view_point(v: View, p: vec2f) -> vec3f {
    return view_point_from(v, p, shutter_project(view_ray(v, p)));
}

// As `view_point`, the rolling shutter corrected with the block's `Shutter`.
fn view_point_in(v: View, p: vec2f, s: Shutter) -> vec3f {
    return view_point_from(v, p, shutter_project_in(view_ray(v, p), s));
}

// The lens-frame ray of point p of a rectified view (rectilinear or panorama).
fn view_ray(v: View, p: vec2f) -> vec3f {
    let m = mat3x3f(v.m0.xyz, v.m1.xyz, v.m2.xyz);
    let k = v.p;
    let a = (p.x - k.z) * k.x;
    let e = k.y - (p.y - k.w) * k.x;
    let panorama = vec3f(cos(e) * cos(a), cos(e) * sin(a), -sin(e));
    let rectilinear = vec3f(k.x, p.x - k.y, p.y - k.z);
    let panoramas = (VIEW_KINDS & (1u << KIND_PANORAMA)) != 0u;
    return m * select(rectilinear, panorama, panoramas && v.kind.x == KIND_PANORAMA);
}

// View point p: `rectified` where the view is rectified, else the fisheye view's own point.
fn view_point_from(v: View, p: vec2f, rectified: vec3f) -> vec3f {
    let k = v.p;
    let kind = v.kind.x;
    let rectified_kinds = (VIEW_KINDS & ((1u << KIND_RECTILINEAR) | (1u << KIND_PANORAMA))) != 0u;
    let fisheyes = (VIEW_KINDS & (1u << KIND_FISHEYE)) != 0u;
    let q = k.xy + p * k.z - 0.5;
    let fisheye = vec3f(q, select(0.0, 1.0, lens_images(q)));
    let drawn = select(rectified, fisheye, fisheyes && (kind == KIND_FISHEYE || !rectified_kinds));
    return select(vec3f(0.0), drawn, kind != KIND_BLACK);
}


// The rolling shutter's rotation at fisheye point q: `ShutterTable::at` (nlerp between the
// knots around the point's knot coordinate).
fn shutter_at(q: vec2f) -> vec4f {
    return shutter_rotation(knot_of(q));
}

// `lens_project` of a lens-frame ray (as the lens was at the frame's middle row), corrected
// for the rolling shutter where the frame has one: `FramePlan::lens_pixel`, projected again
// SHUTTER_STEPS times with the rotation of the row it landed on. Black where any projection
// falls outside the lens's fov, as there.
fn shutter_project(d: vec3f) -> vec3f {
    if !corrects_shutter() {
        return lens_project(d);
    }
    var q = lens_point(d);
    var imaged = q.z;
    for (var i = 0u; i < SHUTTER_STEPS; i++) {
        q = lens_point(rotate(shutter_at(q.xy), d));
        imaged = min(imaged, q.z);
    }
    return vec3f(q.xy, select(0.0, 1.0, imaged > 0.0 && in_frame(q.xy)));
}

// Whether the frame has a rolling shutter to correct (the code is left out of pipelines
// built without SHUTTER_BIT).
fn corrects_shutter() -> bool {
    return (VIEW_KINDS & (1u << SHUTTER_BIT)) != 0u && params.shutter_line.w > 0.0;
}

// The rolling-shutter correction a block's pixels share: the rotation `rot` of knot
// coordinate `k`, the row where the block's first pixel lands, and `g`, how far (fisheye
// pixels) a ray near it moves per knot coordinate of rotation there. A pixel projected with
// `rot` is moved along `g` by the knot coordinates between `k` and the row it lands on then
// (a linear equation, `shutter_project_in`): one projection a pixel where the exact
// iteration (`shutter_project`) takes 1 + SHUTTER_STEPS, within a few hundredths of a
// fisheye pixel of it at 90°/s and a 25 ms readout (tests/it/rolling_shutter.rs).
struct Shutter {
    rot: vec4f,
    g: vec2f,
    k: f32,
    // The block's first pixel, corrected (`view_point_in` of it, projected on the way).
    first: vec3f,
}

// The step in knot coordinates over which `g` is measured.
const SHUTTER_DK: f32 = 0.25;

// The knot coordinate of fisheye point q, not clamped.
fn knot_of(q: vec2f) -> f32 {
    return dot(params.shutter_line.xyz, vec3f(q, 1.0));
}

// The rotation at knot coordinate k: `ShutterTable::at` (nlerp between the knots around it).
fn shutter_rotation(k: f32) -> vec4f {
    let c = clamp(k, 0.0, f32(KNOTS - 1u));
    let i = min(u32(floor(c)), KNOTS - 2u);
    return normalize(mix(params.shutter[i], params.shutter[i + 1u], c - f32(i)));
}

// The `Shutter` of the block whose first pixel is point p of view v (a rectified view).
fn block_shutter(v: View, p: vec2f) -> Shutter {
    let d = view_ray(v, p);
    var s = Shutter(vec4f(0.0, 0.0, 0.0, 1.0), vec2f(0.0), 0.0, vec3f(0.0));
    if !corrects_shutter() {
        s.first = view_point_from(v, p, lens_project(d));
        return s;
    }
    s.k = clamp(knot_of(lens_point(d).xy), 0.0, f32(KNOTS - 1u));
    s.rot = shutter_rotation(s.k);
    let dk = select(SHUTTER_DK, -SHUTTER_DK, s.k + SHUTTER_DK > f32(KNOTS - 1u));
    let q0 = lens_point(rotate(s.rot, d));
    let q1 = lens_point(rotate(shutter_rotation(s.k + dk), d));
    s.g = select(vec2f(0.0), (q1.xy - q0.xy) / dk, q0.z > 0.0 && q1.z > 0.0);
    s.first = view_point_from(v, p, moved_to_its_row(q0, s));
    return s;
}

// `shutter_project` with the block's `Shutter`: projected once with its rotation, then
// moved along g to the row it lands on.
fn shutter_project_in(d: vec3f, s: Shutter) -> vec3f {
    if !corrects_shutter() {
        return lens_project(d);
    }
    return moved_to_its_row(lens_point(rotate(s.rot, d)), s);
}

// Point q, projected with the block's rotation, moved along g to the row k' it lands on:
// k' = knot_of(q + (k' - k) g), linear in k'.
fn moved_to_its_row(q: vec3f, s: Shutter) -> vec3f {
    let lg = dot(params.shutter_line.xy, s.g);
    let landed = clamp((knot_of(q.xy) - s.k * lg) / (1.0 - lg), 0.0, f32(KNOTS - 1u));
    let moved = q.xy + (landed - s.k) * s.g;
    return vec3f(moved, select(0.0, 1.0, q.z > 0.0 && in_frame(moved)));
}

// View `vi` at output pixel (x, y); black where there is no view or the pixel is padding.
fn view_pixel(vi: i32, x: u32, y: u32) -> vec3f {
    let q = view_point(views[max(vi, 0)], view_xy(views[max(vi, 0)], x, y));
    return select(vec3f(0.0), q, vi >= 0 && x < params.output.x);
}

// Output pixel (x, y)'s centre in view `v`'s own pixel coordinates.
fn view_xy(v: View, x: u32, y: u32) -> vec2f {
    return vec2f(f32(x) - f32(v.rect.x), f32(y) - f32(v.rect.y)) + 0.5;
}

// Where one row of a block lands, pixel by pixel (columns 0 to 7).
struct Run {
    c0: vec3f,
    c1: vec3f,
    c2: vec3f,
    c3: vec3f,
    c4: vec3f,
    c5: vec3f,
    c6: vec3f,
    c7: vec3f,
}

// Point x of the parabola through `a`, `b` and `c` at columns 0, 4 and 7.
fn through(a: vec3f, b: vec3f, c: vec3f, x: f32) -> vec2f {
    return a.xy * ((x - 4.0) * (x - 7.0) / 28.0) + b.xy * (x * (x - 7.0) / -12.0)
        + c.xy * (x * (x - 4.0) / 21.0);
}

// The farthest column 2 of a run may land from the parabola through columns 0, 4 and 7 for
// the run's other pixels to be put on it, in fisheye pixels.
const RUN_TOLERANCE: f32 = 0.005;

// Where the row of 8 pixels from `p` in view `v` lands (`c0`, the first, given): projected
// at columns 0, 2, 4 and 7 and, where all four are imaged and column 2 lies within
// RUN_TOLERANCE of the parabola through the others, columns 1, 3, 5 and 6 put on that
// parabola; else every pixel projected. Eight of a block's 16 projections go, and with
// them about a tenth of the draw's time on lavapipe; measured against the exact projection over every lens model, crop mode
// and fields of view up to 300°, no pixel put on a parabola lands more than 0.005 fisheye
// pixels from where it projects (tests/gpu_render.rs, docs/decisions.md).
fn run_of(v: View, p: vec2f, s: Shutter, c0: vec3f) -> Run {
    let c2 = view_point_in(v, p + vec2f(2.0, 0.0), s);
    let c4 = view_point_in(v, p + vec2f(4.0, 0.0), s);
    let c7 = view_point_in(v, p + vec2f(7.0, 0.0), s);
    var r = Run(c0, c0, c2, c2, c4, c4, c4, c7);
    let imaged = min(min(c0.z, c2.z), min(c4.z, c7.z)) > 0.0;
    if imaged && distance(through(c0, c4, c7, 2.0), c2.xy) <= RUN_TOLERANCE {
        r.c1 = vec3f(through(c0, c4, c7, 1.0), 1.0);
        r.c3 = vec3f(through(c0, c4, c7, 3.0), 1.0);
        r.c5 = vec3f(through(c0, c4, c7, 5.0), 1.0);
        r.c6 = vec3f(through(c0, c4, c7, 6.0), 1.0);
    } else {
        r.c1 = view_point_in(v, p + vec2f(1.0, 0.0), s);
        r.c3 = view_point_in(v, p + vec2f(3.0, 0.0), s);
        r.c5 = view_point_in(v, p + vec2f(5.0, 0.0), s);
        r.c6 = view_point_in(v, p + vec2f(6.0, 0.0), s);
    }
    return r;
}
