//! The ground model: WGS84 positions to and from the vehicle's local NED frame, and where a
//! ray meets the ground plane (a horizontal plane at the home altitude, conventions.md).

use glam::{DMat3, DVec3};
use serde::{Deserialize, Serialize};

const A: f64 = 6_378_137.0;
const F: f64 = 1.0 / 298.257_223_563;
const E2: f64 = F * (2.0 - F);

/// Rays that meet the ground further than this have no ground point.
pub const MAX_GROUND_RANGE: f64 = 10_000.0;

/// A WGS84 point: degrees, metres above mean sea level.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct GeoPoint {
    pub lat: f64,
    pub lon: f64,
    pub alt: f64,
}

/// The vehicle's position as GLOBAL_POSITION_INT gives it: a WGS84 point and the height
/// above home, so the home (ground) altitude is `alt - relative_alt`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct GeoPosition {
    pub lat: f64,
    pub lon: f64,
    pub alt: f64,
    pub relative_alt: f64,
}

impl Default for GeoPosition {
    /// 50 m above a home at sea level on the equator and prime meridian.
    fn default() -> Self {
        GeoPosition {
            lat: 0.0,
            lon: 0.0,
            alt: 50.0,
            relative_alt: 50.0,
        }
    }
}

impl GeoPosition {
    pub fn point(&self) -> GeoPoint {
        GeoPoint {
            lat: self.lat,
            lon: self.lon,
            alt: self.alt,
        }
    }
    pub fn home_alt(&self) -> f64 {
        self.alt - self.relative_alt
    }
}

pub fn to_ecef(p: GeoPoint) -> DVec3 {
    let (lat, lon) = (p.lat.to_radians(), p.lon.to_radians());
    let n = A / (1.0 - E2 * lat.sin().powi(2)).sqrt();
    DVec3::new(
        (n + p.alt) * lat.cos() * lon.cos(),
        (n + p.alt) * lat.cos() * lon.sin(),
        (n * (1.0 - E2) + p.alt) * lat.sin(),
    )
}

pub fn from_ecef(e: DVec3) -> GeoPoint {
    let lon = e.y.atan2(e.x);
    let p = e.x.hypot(e.y);
    // Fixed-point iteration on latitude; converges to 1e-12 rad in a handful of steps.
    let mut lat = e.z.atan2(p * (1.0 - E2));
    let mut alt = 0.0;
    for _ in 0..10 {
        let n = A / (1.0 - E2 * lat.sin().powi(2)).sqrt();
        alt = if lat.cos().abs() > 1e-9 {
            p / lat.cos() - n
        } else {
            e.z.abs() - n * (1.0 - E2)
        };
        lat = e.z.atan2(p * (1.0 - E2 * n / (n + alt)));
    }
    GeoPoint {
        lat: lat.to_degrees(),
        lon: lon.to_degrees(),
        alt,
    }
}

/// Rotation from ECEF to the NED frame at a point.
fn ned_from_ecef(origin: GeoPoint) -> DMat3 {
    let (sl, cl) = origin.lat.to_radians().sin_cos();
    let (so, co) = origin.lon.to_radians().sin_cos();
    // Rows: north, east, down.
    DMat3::from_cols(
        DVec3::new(-sl * co, -so, -cl * co),
        DVec3::new(-sl * so, co, -cl * so),
        DVec3::new(cl, 0.0, -sl),
    )
}

/// A point's NED coordinates (metres) relative to `origin`.
pub fn to_ned(origin: GeoPoint, p: GeoPoint) -> DVec3 {
    ned_from_ecef(origin) * (to_ecef(p) - to_ecef(origin))
}

/// The WGS84 point at NED offset `ned` from `origin`.
pub fn from_ned(origin: GeoPoint, ned: DVec3) -> GeoPoint {
    from_ecef(to_ecef(origin) + ned_from_ecef(origin).transpose() * ned)
}

/// Where a world (NED) ray from the vehicle meets the ground plane, as an NED offset from the
/// vehicle; None if it points at or above the horizon, the vehicle is not above home, or the
/// point is further than 10 km.
pub fn ray_to_ground(position: &GeoPosition, ray: DVec3) -> Option<DVec3> {
    let ray = ray.normalize();
    let height = position.relative_alt;
    if height.is_nan() || height <= 0.0 || ray.z <= 1e-9 {
        return None;
    }
    let range = height / ray.z;
    (range <= MAX_GROUND_RANGE).then(|| ray * range)
}

/// The geographic point a ray from the vehicle sees on the ground, and its range in metres.
pub fn ground_point(position: &GeoPosition, ray: DVec3) -> Option<(GeoPoint, f64)> {
    let ned = ray_to_ground(position, ray)?;
    Some((from_ned(position.point(), ned), ned.length()))
}

/// The world ray from the vehicle towards a geographic target (CAM_TARGET), None if the target
/// is where the vehicle is.
pub fn ray_to_target(position: &GeoPosition, target: GeoPoint) -> Option<DVec3> {
    let v = to_ned(position.point(), target);
    (v.length() > 1e-6).then(|| v.normalize())
}
