//! How a view's pixels are filtered where the fisheye is minified: the choice a plan makes per
//! view ([`super::FramePlan::cheapest_filter`]) and both renderers carry out
//! (`crate::render::mip` defines the mip chain itself).

/// The most mip levels kept: enough for 128x minification.
pub const MAX_LEVELS: u32 = 8;

/// How minified views are filtered.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Filter {
    /// Trilinear from the mip chain at each pixel's footprint (the default).
    #[default]
    Mip,
    /// One bilinear sample of the full-size frame: sharper, aliases when minified.
    Bilinear,
}

impl Filter {
    /// The code the shader uses (`FILTER_*` in shaders/render.wgsl).
    pub fn shader_code(self) -> u32 {
        self as u32
    }
}
