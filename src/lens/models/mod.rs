//! The lens models and their registry. Every model is rotationally symmetric about the optical
//! axis in its own normalized plane, so it is a radial function r(θ), θ = atan2(ρ, z) the
//! angle from the axis (valid beyond 90°), and its inverse; the pixel affine that follows is
//! the lens's (`PixelAffine`).
//!
//! A model is one file here holding a struct of its coefficients and its [`RadialModel`] impl
//! (the f64 math, its lens.cal fields, what its WGSL twin reads, a sample lens for the
//! tests), one WGSL function `NAME_r` in
//! shaders/lens.wgsl, and one line in `registry!` below, which declares its file, makes it a
//! variant of [`Model`], gives it its code for the GPU's LENS_MODEL override (shaders.rs makes
//! the WGSL dispatch from [`Model::NAMES`]), and makes lens.cal read and write it.

mod solve;

use super::calfile::{Fields, TomlWriter};
use super::{LensError, PixelAffine};

/// Where a model stops being one-to-one: θ and the normalized radius there.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ModelLimits {
    pub theta_max: f64,
    pub r_max: f64,
}

impl ModelLimits {
    /// The limits of a model that is one-to-one up to `theta_max`: r there, once.
    pub fn up_to(model: &impl RadialModel, theta_max: f64) -> ModelLimits {
        let open = ModelLimits {
            theta_max,
            r_max: f64::INFINITY,
        };
        ModelLimits {
            theta_max,
            r_max: model.r_of_theta(theta_max, &open).unwrap_or(f64::INFINITY),
        }
    }
}

/// What a model's WGSL twin reads from the lens uniform (`Lens` in shaders/lens.wgsl): four
/// numbers in `k`, and polynomials in `pol` and `invpol`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Coefficients<'a> {
    pub k: [f64; 4],
    pub pol: &'a [f64],
    pub invpol: &'a [f64],
}

/// A lens of one model, as the tests take it (`crate::lens::samples`).
#[derive(Clone, Debug, PartialEq)]
pub struct Sample<M> {
    pub model: M,
    pub affine: PixelAffine,
    /// The valid field of view, radians.
    pub fov: f64,
}

/// The pixel affine of the classic models' samples: focal length `f` (fy 0.2% longer), the
/// principal point a little off the centre of a 1280x960 frame.
pub fn sample_pinhole(f: f64) -> PixelAffine {
    PixelAffine::pinhole(f, f * 1.002, 641.3, 479.2)
}

/// One lens model: its radial function both ways, where it is one-to-one, how lens.cal
/// writes it, what the GPU reads of it, and a lens of it to test with.
pub trait RadialModel: Sized {
    /// Its name in lens.cal; its WGSL twin is `NAME_r` in shaders/lens.wgsl.
    const NAME: &'static str;
    /// Reads the model's coefficients and the pixel affine from a lens.cal entry.
    fn read(fields: &Fields) -> Result<(Self, PixelAffine), LensError>;
    /// Writes what [`RadialModel::read`] reads: by default the pinhole affine alone.
    fn write(&self, affine: &PixelAffine, out: &mut TomlWriter) {
        out.pinhole(affine);
    }
    /// Where the model is one-to-one (worked out once per lens).
    fn limits(&self) -> ModelLimits;
    /// Normalized radius for a ray at angle θ (within the limits) from the axis.
    fn r_of_theta(&self, theta: f64, limits: &ModelLimits) -> Option<f64>;
    /// Angle from the axis for a normalized radius (within the limits).
    fn theta_of_r(&self, r: f64, limits: &ModelLimits) -> Option<f64>;
    /// What its WGSL twin reads; nothing by default.
    fn coefficients(&self) -> Coefficients<'_> {
        Coefficients::default()
    }
    /// A lens of this model in a 1280x960 frame, with coefficients typical of real
    /// calibrations and near its widest field of view: every model test, the lens.cal round
    /// trip and the GPU parity tests run on it.
    fn sample() -> Sample<Self>;
}

/// Makes [`Model`] from the list of models, each `Name(file)` with `file.rs` holding the struct
/// `Name`: the file's module, a variant per model, its code (the position in the list) and
/// dispatch to each model's [`RadialModel`] impl.
macro_rules! registry {
    ($($variant:ident($file:ident),)+) => {
        $(
            pub mod $file;
            pub use $file::$variant;
        )+

        /// A lens model with its coefficients.
        #[derive(Clone, Debug, PartialEq)]
        pub enum Model {
            $($variant($variant),)+
        }

        /// The models' codes, in the order they are listed.
        #[derive(Clone, Copy)]
        enum Code {
            $($variant,)+
        }

        impl Model {
            /// Every model's lens.cal name, by code.
            pub const NAMES: &[&str] = &[$(<$variant as RadialModel>::NAME,)+];

            pub fn name(&self) -> &'static str {
                Self::NAMES[self.code() as usize]
            }

            /// The model's code: the GPU's LENS_MODEL override.
            pub fn code(&self) -> u32 {
                (match self {
                    $(Model::$variant(_) => Code::$variant,)+
                }) as u32
            }

            /// Reads a model named `name` from a lens.cal entry; None for an unknown name.
            pub fn read(
                name: &str,
                fields: &Fields,
            ) -> Option<Result<(Model, PixelAffine), LensError>> {
                $(if name == <$variant as RadialModel>::NAME {
                    return Some(<$variant>::read(fields).map(|(m, a)| (Model::$variant(m), a)));
                })+
                None
            }

            pub fn write(&self, affine: &PixelAffine, out: &mut TomlWriter) {
                match self {
                    $(Model::$variant(m) => m.write(affine, out),)+
                }
            }

            pub fn limits(&self) -> ModelLimits {
                match self {
                    $(Model::$variant(m) => m.limits(),)+
                }
            }

            fn r_of_theta(&self, theta: f64, limits: &ModelLimits) -> Option<f64> {
                match self {
                    $(Model::$variant(m) => m.r_of_theta(theta, limits),)+
                }
            }

            fn theta_of_r(&self, r: f64, limits: &ModelLimits) -> Option<f64> {
                match self {
                    $(Model::$variant(m) => m.theta_of_r(r, limits),)+
                }
            }

            pub fn coefficients(&self) -> Coefficients<'_> {
                match self {
                    $(Model::$variant(m) => m.coefficients(),)+
                }
            }

            /// Every model's sample lens, by code.
            pub fn samples() -> Vec<Sample<Model>> {
                vec![$({
                    let s = <$variant as RadialModel>::sample();
                    Sample {
                        model: Model::$variant(s.model),
                        affine: s.affine,
                        fov: s.fov,
                    }
                },)+]
            }
        }
    };
}

registry! {
    Equidistant(equidistant),
    Equisolid(equisolid),
    Stereographic(stereographic),
    Orthographic(orthographic),
    KannalaBrandt(kannala_brandt),
    DoubleSphere(double_sphere),
    Ocam(ocam),
    Pinhole(pinhole),
}

/// The radial model with its limits worked out once.
#[derive(Clone, Debug, PartialEq)]
pub struct Radial {
    pub model: Model,
    pub limits: ModelLimits,
}

impl Radial {
    pub fn new(model: Model) -> Self {
        let limits = model.limits();
        Radial { model, limits }
    }

    /// Normalized radius for a ray at angle θ from the axis; None beyond the model's limit.
    pub fn r_of_theta(&self, theta: f64) -> Option<f64> {
        if !(0.0..=self.limits.theta_max + 1e-12).contains(&theta) {
            return None;
        }
        self.model.r_of_theta(theta, &self.limits)
    }

    /// Angle from the axis for a normalized radius; None beyond the model's limit.
    pub fn theta_of_r(&self, r: f64) -> Option<f64> {
        if !(0.0..=self.limits.r_max * (1.0 + 1e-12)).contains(&r) {
            return None;
        }
        self.model.theta_of_r(r, &self.limits)
    }
}
