//! One lens of every model, each with coefficients typical of real calibrations and near its
//! widest field of view (each model's `RadialModel::sample`): what the model tests, the GPU
//! parity tests and the benchmarks run on where the shipped lenses (three models) do not
//! cover a model. A model added to the registry is in this list, and so in every one of those
//! tests, at once.

use super::{Lens, Model};

/// One lens per model, in the registry's order, named after its model and numbered by its
/// code, in a 1280x960 frame.
pub fn sample_lenses() -> Vec<Lens> {
    Model::samples()
        .into_iter()
        .map(|s| {
            let (name, id) = (s.model.name(), s.model.code() as u8);
            Lens::new(name, id, s.model, s.affine, (1280, 960), s.fov)
        })
        .collect()
}
