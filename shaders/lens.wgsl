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

// The model's code, with PAIR_BIT for a pair of lenses (`Lens::shader_model`): a single
// lens's pipelines leave the pair's code out.
override LENS_MODEL: u32 = 0u;
const PAIR_BIT: u32 = 256u;

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
    // A lens pair's second lens (src/lens/pair.rs; zero for one lens): its matrix, inverse,
    // principal point (xy; z is 1 for a pair), limits and coefficients as the first's above,
    // and the rotation of a ray from the first lens's frame into its own (quaternion xyzw).
    second_affine: vec4f,
    second_inverse: vec4f,
    second_offset: vec4f,
    second_limits: vec4f,
    second_k: vec4f,
    second_from_first: vec4f,
}

fn equidistant_r(theta: f32, k: vec4f) -> f32 {
    return theta;
}

fn equisolid_r(theta: f32, k: vec4f) -> f32 {
    return 2.0 * sin(0.5 * theta);
}

fn stereographic_r(theta: f32, k: vec4f) -> f32 {
    return 2.0 * tan(0.5 * theta);
}

fn orthographic_r(theta: f32, k: vec4f) -> f32 {
    return sin(theta);
}

fn kannala_brandt_r(theta: f32, k: vec4f) -> f32 {
    let t2 = theta * theta;
    return theta * (1.0 + t2 * (k.x + t2 * (k.y + t2 * (k.z + t2 * k.w))));
}

fn pinhole_r(theta: f32, k: vec4f) -> f32 {
    let t = tan(theta);
    let t2 = t * t;
    return t * (1.0 + t2 * (k.x + t2 * (k.y + t2 * k.z)));
}

// Negative where the model does not project (its denominator vanishes).
fn double_sphere_r(theta: f32, k: vec4f) -> f32 {
    let xi = k.x;
    let alpha = k.y;
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
// steps on the direct polynomial, as src/lens/models/ocam.rs does in f64. Its coefficients
// are the lens's polynomials, not `k` (a pair's lenses are never OCam's).
fn ocam_r(theta: f32, k: vec4f) -> f32 {
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

// Vector v turned by unit quaternion q (x, y, z, w).
fn rotate(q: vec4f, v: vec3f) -> vec3f {
    let t = 2.0 * cross(q.xyz, v);
    return v + q.w * t + cross(q.xyz, t);
}

// Whether the lens is a pair of two back to back.
fn is_pair() -> bool {
    return (LENS_MODEL & PAIR_BIT) != 0u;
}

// Where a ray in one lens's own frame lands through that lens (its pixel matrix `affine`,
// principal point `offset`, half field of view `half_fov`, coefficients `k`), and whether it
// images it at all (z = 1; else z = 0 and xy = 0).
fn part_point(ray: vec3f, affine: vec4f, offset: vec2f, half_fov: f32, k: vec4f) -> vec3f {
    let rho = length(ray.xy);
    let theta = atan2(rho, ray.z);
    if theta > half_fov {
        return vec3f(0.0);
    }
    let r = radial_r(theta, k);
    if r < 0.0 {
        return vec3f(0.0);
    }
    var dir = vec2f(0.0);
    if rho > 0.0 {
        dir = ray.xy * (1.0 / rho);
    }
    let m = dir * r;
    let q = vec2f(affine.x * m.x + affine.z * m.y, affine.y * m.x + affine.w * m.y) + offset;
    return vec3f(q, 1.0);
}

fn first_point(ray: vec3f) -> vec3f {
    return part_point(
        ray,
        params.lens.affine,
        params.lens.offset_frame.xy,
        params.lens.limits.x,
        params.lens.k,
    );
}

// `ray` already turned into the second lens's frame.
fn second_point(ray: vec3f) -> vec3f {
    return part_point(
        ray,
        params.lens.second_affine,
        params.lens.second_offset.xy,
        params.lens.second_limits.x,
        params.lens.second_k,
    );
}

// Where a lens-frame ray lands (xy) and whether the lens images it at all (z = 1; else z = 0
// and xy = 0): src/lens/mod.rs's `Lens::project`, the frame's edges not yet considered. A
// pair draws the ray from the lens it lies deeper inside (`Pair::project`), else the other.
fn lens_point(ray: vec3f) -> vec3f {
    if !is_pair() {
        return first_point(ray);
    }
    let turned = rotate(params.lens.second_from_first, ray);
    let first_margin = params.lens.limits.x - atan2(length(ray.xy), ray.z);
    let second_margin = params.lens.second_limits.x - atan2(length(turned.xy), turned.z);
    let first = first_margin >= second_margin;
    var q = select(second_point(turned), first_point(ray), first);
    if q.z == 0.0 {
        q = select(first_point(ray), second_point(turned), first);
    }
    return q;
}

// Where a lens-frame ray lands (xy) and whether it is imaged there (z = 1) or black (z = 0):
// src/lens/mod.rs's `Lens::project` followed by `Lens::in_frame`.
fn lens_project(ray: vec3f) -> vec3f {
    let q = lens_point(ray);
    return vec3f(q.xy, select(0.0, 1.0, q.z > 0.0 && in_frame(q.xy)));
}

// Whether a fisheye pixel lies in the second lens's image of a pair (`Pair::side_at`: nearer
// its centre along the line between the two centres).
fn in_second(q: vec2f) -> bool {
    let a = params.lens.offset_frame.xy;
    let b = params.lens.second_offset.xy;
    return is_pair() && dot(q - 0.5 * (a + b), b - a) > 0.0;
}

// Whether two fisheye pixels lie in the same image (always, but for a pair).
fn same_image(a: vec2f, b: vec2f) -> bool {
    return in_second(a) == in_second(b);
}

// Whether a fisheye pixel lies inside the image circle and the frame (`Lens::unproject` is
// Some and `Lens::in_frame`): its normalized radius within the radius at half_fov, in the
// image (of a pair's two) that holds it.
fn lens_images(q: vec2f) -> bool {
    let second = in_second(q);
    let d = q - select(params.lens.offset_frame.xy, params.lens.second_offset.xy, second);
    let inverse = select(params.lens.inverse, params.lens.second_inverse, second);
    let m = vec2f(inverse.x * d.x + inverse.z * d.y, inverse.y * d.x + inverse.w * d.y);
    let limit = select(params.lens.limits.y, params.lens.second_limits.y, second);
    return length(m) <= limit && in_frame(q);
}
