// The lens-model library every pass that maps rays to fisheye pixels shares: one function
// `NAME_r(theta)` per model of src/lens/models/, NAME its lens.cal name (`kannala_brandt_r`
// twins src/lens/models/kannala_brandt.rs's `r_of_theta`), in f32. The model is chosen when
// the pipeline is built (the LENS_MODEL override, a model's code), so a frame pays for one
// model only: `radial_r`, which calls the chosen one, is made from the models' registry by
// src/render/gpu/shaders.rs.
//
// Prepended to a pass's own source by src/render/gpu/shaders.rs. The functions read the lens
// from `params.lens`, the uniform each pass that includes this file declares (a by-value
// copy would be a private array, which software rasterizers index lane by lane).

override LENS_MODEL: u32 = 0u;

// Twin of the Rust `GpuLens` (src/render/gpu/params.rs); vec4s only, so no padding rules bite.
struct Lens {
    // Normalized plane → pixel: columns of the 2x2 matrix (xy, zw).
    affine: vec4f,
    // Its inverse, pixel → normalized plane.
    inverse: vec4f,
    // The principal point (xy) and the fisheye frame's size (zw).
    offset_frame: vec4f,
    // half_fov, normalized radius at half_fov, the model's θ limit and radius limit.
    limits: vec4f,
    // Kannala-Brandt k1..k4; pinhole k1..k3; Double Sphere (ξ, α).
    k: vec4f,
    // OCam: number of pol and invpol coefficients.
    counts: vec4u,
    pol: array<vec4f, 2>,
    invpol: array<vec4f, 6>,
}

fn equidistant_r(theta: f32) -> f32 {
    return theta;
}

fn equisolid_r(theta: f32) -> f32 {
    return 2.0 * sin(0.5 * theta);
}

fn stereographic_r(theta: f32) -> f32 {
    return 2.0 * tan(0.5 * theta);
}

fn orthographic_r(theta: f32) -> f32 {
    return sin(theta);
}

fn kannala_brandt_r(theta: f32) -> f32 {
    let k = params.lens.k;
    let t2 = theta * theta;
    return theta * (1.0 + t2 * (k.x + t2 * (k.y + t2 * (k.z + t2 * k.w))));
}

fn pinhole_r(theta: f32) -> f32 {
    let k = params.lens.k;
    let t = tan(theta);
    let t2 = t * t;
    return t * (1.0 + t2 * (k.x + t2 * (k.y + t2 * k.z)));
}

// Negative where the model does not project (its denominator vanishes).
fn double_sphere_r(theta: f32) -> f32 {
    let xi = params.lens.k.x;
    let alpha = params.lens.k.y;
    let s = sin(theta);
    let c = cos(theta);
    let d2 = sqrt(s * s + (xi + c) * (xi + c));
    let denom = alpha * d2 + (1.0 - alpha) * (xi + c);
    if denom <= 1e-6 {
        return -1.0;
    }
    return s / denom;
}

fn coefficient(which: u32, i: u32) -> f32 {
    if which == 0u {
        return params.lens.pol[i / 4u][i % 4u];
    }
    return params.lens.invpol[i / 4u][i % 4u];
}

fn ocam_poly(which: u32, x: f32) -> f32 {
    let n = params.lens.counts[which];
    var acc = 0.0;
    for (var i = n; i > 0u; i--) {
        acc = acc * x + coefficient(which, i - 1u);
    }
    return acc;
}

// The direct polynomial's derivative (0 for no coefficients: a lens of another model, read
// as OCam when its pipelines are warmed up, must not loop 2^32 times).
fn ocam_dpoly(x: f32) -> f32 {
    let n = params.lens.counts.x;
    var acc = 0.0;
    for (var i = n; i > 1u; i--) {
        acc = acc * x + f32(i - 1u) * coefficient(0u, i - 1u);
    }
    return acc;
}

// θ(r) = atan2(r, -pol(r)) inverted: the inverse polynomial's guess, then bracketed Newton
// steps on the direct polynomial, as src/lens/models/ocam.rs does in f64.
fn ocam_r(theta: f32) -> f32 {
    let r_max = params.lens.limits.w;
    var lo = 0.0;
    var hi = r_max;
    var r = 0.5 * r_max;
    if params.lens.counts.y > 0u {
        r = clamp(ocam_poly(1u, theta - 1.5707964), 0.0, r_max);
    }
    for (var i = 0; i < 12; i++) {
        let p = ocam_poly(0u, r);
        let f = atan2(r, -p) - theta;
        if abs(f) <= 1e-7 {
            break;
        }
        if f > 0.0 {
            hi = r;
        } else {
            lo = r;
        }
        let d = (-p + r * ocam_dpoly(r)) / (r * r + p * p);
        let next = r - f / d;
        if d > 0.0 && next >= lo && next <= hi {
            r = next;
        } else {
            r = 0.5 * (lo + hi);
        }
    }
    return r;
}

// FRAME_EDGE_SLACK as in src/lens/mod.rs: a ray that lands exactly on the frame's edge (the
// debug view puts its rows there) is in, whichever way f32 rounds.
fn in_frame(q: vec2f) -> bool {
    let size = params.lens.offset_frame.zw;
    return all(q >= vec2f(-0.501)) && all(q <= size - 0.499);
}

// Where a lens-frame ray lands (xy) and whether the lens images it at all (z = 1; else z = 0
// and xy = 0): src/lens/mod.rs's `Lens::project`, the frame's edges not yet considered.
fn lens_point(ray: vec3f) -> vec3f {
    let affine = params.lens.affine;
    let rho = length(ray.xy);
    let theta = atan2(rho, ray.z);
    if theta > params.lens.limits.x {
        return vec3f(0.0);
    }
    let r = radial_r(theta);
    if r < 0.0 {
        return vec3f(0.0);
    }
    var dir = vec2f(0.0);
    if rho > 0.0 {
        dir = ray.xy * (1.0 / rho);
    }
    let m = dir * r;
    let q = vec2f(
        affine.x * m.x + affine.z * m.y,
        affine.y * m.x + affine.w * m.y,
    ) + params.lens.offset_frame.xy;
    return vec3f(q, 1.0);
}

// Where a lens-frame ray lands (xy) and whether it is imaged there (z = 1) or black (z = 0):
// src/lens/mod.rs's `Lens::project` followed by `Lens::in_frame`.
fn lens_project(ray: vec3f) -> vec3f {
    let q = lens_point(ray);
    return vec3f(q.xy, select(0.0, 1.0, q.z > 0.0 && in_frame(q.xy)));
}

// Whether a fisheye pixel lies inside the image circle and the frame (`Lens::unproject` is
// Some and `Lens::in_frame`): its normalized radius within the radius at half_fov.
fn lens_images(q: vec2f) -> bool {
    let d = q - params.lens.offset_frame.xy;
    let inverse = params.lens.inverse;
    let m = vec2f(inverse.x * d.x + inverse.z * d.y, inverse.y * d.x + inverse.w * d.y);
    return length(m) <= params.lens.limits.y && in_frame(q);
}
