//! DETECTION's settings in the live state, and how the protocol's DETECTION reads and sets
//! them (the seed's rules), so every path that sets them applies the same ones.

use crate::protocol::params::Detection;
use serde::{Deserialize, Serialize};

/// A score field of 255 means "keep the current value".
pub const KEEP: u8 = 255;

/// How detections are kept and shown (DETECTION, and GENERAL_SETTINGS' run_ai). Field names
/// are the seed's; ratios are in [0, 1).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DetectionSettings {
    pub run_ai: bool,
    /// Unused by the seed; kept for GET.
    pub mode: u8,
    /// 0 by score, 1 by age, 2 by score with tiles locked to their object.
    pub sorting_mode: u8,
    pub crop_confidence_threshold: f64,
    pub var_confidence_threshold: f64,
    pub crop_box_limit: u16,
    pub var_box_limit: u16,
    pub crop_box_overlap: f64,
    pub var_box_overlap: f64,
    pub creation_score_scale: u8,
    pub bonus_detection_scale: u8,
    pub bonus_redetection_scale: u8,
    pub missed_detection_penalty: u8,
    pub missed_redetection_penalty: u8,
}

impl Default for DetectionSettings {
    fn default() -> Self {
        DetectionSettings {
            run_ai: true,
            mode: 0,
            sorting_mode: 0,
            crop_confidence_threshold: 0.5,
            var_confidence_threshold: 0.3,
            crop_box_limit: 100,
            var_box_limit: 100,
            crop_box_overlap: 0.5,
            var_box_overlap: 0.5,
            creation_score_scale: 50,
            bonus_detection_scale: 10,
            bonus_redetection_scale: 5,
            missed_detection_penalty: 10,
            missed_redetection_penalty: 5,
        }
    }
}

impl DetectionSettings {
    /// DETECTION as GET reports it.
    pub fn param(&self) -> Detection {
        Detection {
            mode: self.mode,
            sorting_mode: self.sorting_mode,
            crop_confidence_threshold: self.crop_confidence_threshold,
            var_confidence_threshold: self.var_confidence_threshold,
            crop_box_limit: self.crop_box_limit,
            var_box_limit: self.var_box_limit,
            crop_box_overlap: self.crop_box_overlap,
            var_box_overlap: self.var_box_overlap,
            creation_score_scale: self.creation_score_scale,
            bonus_detection_scale: self.bonus_detection_scale,
            bonus_redetection_scale: self.bonus_redetection_scale,
            missed_detection_penalty: self.missed_detection_penalty,
            missed_redetection_penalty: self.missed_redetection_penalty,
        }
    }

    /// The seed's rules: mode is ignored; a sorting mode above 2 is ignored; thresholds and
    /// overlaps outside [0, 0.99) keep their value; box limits are clamped to 10..=500; a score
    /// field of 255 keeps its value.
    pub fn set(&mut self, p: &Detection) {
        use super::rules::*;
        let d = self;
        d.sorting_mode = DETECTION_SORTING.take(p.sorting_mode as f64, d.sorting_mode as f64) as u8;
        for (rule, field, v) in [
            (
                &DETECTION_CROP_CONFIDENCE,
                &mut d.crop_confidence_threshold,
                p.crop_confidence_threshold,
            ),
            (
                &DETECTION_VAR_CONFIDENCE,
                &mut d.var_confidence_threshold,
                p.var_confidence_threshold,
            ),
            (
                &DETECTION_CROP_BOX_OVERLAP,
                &mut d.crop_box_overlap,
                p.crop_box_overlap,
            ),
            (
                &DETECTION_VAR_BOX_OVERLAP,
                &mut d.var_box_overlap,
                p.var_box_overlap,
            ),
        ] {
            *field = rule.take(v, *field);
        }
        for (rule, field, v) in [
            (
                &DETECTION_CROP_BOX_LIMIT,
                &mut d.crop_box_limit,
                p.crop_box_limit,
            ),
            (
                &DETECTION_VAR_BOX_LIMIT,
                &mut d.var_box_limit,
                p.var_box_limit,
            ),
        ] {
            *field = rule.take(v as f64, *field as f64) as u16;
        }
        for (rule, field, v) in [
            (
                &DETECTION_CREATION_SCORE,
                &mut d.creation_score_scale,
                p.creation_score_scale,
            ),
            (
                &DETECTION_BONUS_DETECTION,
                &mut d.bonus_detection_scale,
                p.bonus_detection_scale,
            ),
            (
                &DETECTION_BONUS_REDETECTION,
                &mut d.bonus_redetection_scale,
                p.bonus_redetection_scale,
            ),
            (
                &DETECTION_MISSED_DETECTION,
                &mut d.missed_detection_penalty,
                p.missed_detection_penalty,
            ),
            (
                &DETECTION_MISSED_REDETECTION,
                &mut d.missed_redetection_penalty,
                p.missed_redetection_penalty,
            ),
        ] {
            *field = rule.take(v as f64, *field as f64) as u8;
        }
    }
}
