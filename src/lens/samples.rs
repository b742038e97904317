//! One lens of every model, with coefficients typical of real calibrations and each near its
//! widest field of view: what the model tests, the GPU parity tests and the benchmarks run on
//! where the shipped lenses (three models) do not cover a model.

use super::models::{
    DoubleSphere, Equidistant, Equisolid, KannalaBrandt, Ocam, Orthographic, Stereographic,
};
use super::{Lens, Model, PixelAffine};

/// One lens per model with coefficients typical of real calibrations, each near its widest fov.
pub fn sample_lenses() -> Vec<Lens> {
    let size = (1280, 960);
    let pin = |f: f64| PixelAffine::pinhole(f, f * 1.002, 641.3, 479.2);
    let deg = |d: f64| d.to_radians();
    vec![
        Lens::new(
            "equidistant",
            0,
            Model::Equidistant(Equidistant),
            pin(300.0),
            size,
            deg(190.0),
        ),
        Lens::new(
            "equisolid",
            1,
            Model::Equisolid(Equisolid),
            pin(300.0),
            size,
            deg(190.0),
        ),
        Lens::new(
            "stereographic",
            2,
            Model::Stereographic(Stereographic),
            pin(220.0),
            size,
            deg(190.0),
        ),
        Lens::new(
            "orthographic",
            3,
            Model::Orthographic(Orthographic),
            pin(470.0),
            size,
            deg(180.0),
        ),
        Lens::new(
            "kb4",
            4,
            Model::KannalaBrandt(KannalaBrandt {
                k: [0.0423, -0.0126, 0.0031, -0.0004],
            }),
            pin(290.0),
            size,
            deg(195.0),
        ),
        Lens::new(
            "double_sphere",
            5,
            Model::DoubleSphere(DoubleSphere {
                xi: -0.22,
                alpha: 0.58,
            }),
            pin(180.0),
            size,
            deg(190.0),
        ),
        Lens::new(
            "ocam",
            6,
            Model::Ocam(Ocam {
                pol: vec![-190.0, 0.0, 1.1e-3, 2.0e-7, 1.0e-9],
                invpol: vec![280.0, 180.0, 30.0],
            }),
            PixelAffine::ocam(1.0004, 0.0003, -0.0002, 478.6, 640.9),
            size,
            deg(195.0),
        ),
    ]
}
