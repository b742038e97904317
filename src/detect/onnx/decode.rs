//! From a detection model's raw outputs to boxes in its input picture. Two layouts are
//! understood: NanoDet's (per stride, sigmoid class scores and box distances as binned
//! distributions, the model shipped in `assets/models`) and the common YOLOv8 export (one
//! tensor, [1, 4 + classes, anchors], centre and size in input pixels, then class scores).
//! Pure functions over slices, so they are tested without ONNX Runtime.

use glam::DVec2;

/// A box in the model's input picture (pixels, `low` its top-left corner, `high` its
/// bottom-right), with its best class and that class's score.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PixelBox {
    pub low: DVec2,
    pub high: DVec2,
    pub confidence: f32,
    pub class: u16,
}

/// Which layout the model's outputs follow.
#[derive(
    Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize, clap::ValueEnum,
)]
#[serde(rename_all = "lowercase")]
pub enum Decoder {
    Nanodet,
    Yolov8,
}

/// One of NanoDet's levels: its stride, its class scores ([cells, classes]) and its box
/// distances ([cells, 4 × bins], left, top, right, bottom).
pub struct Level<'a> {
    pub stride: u32,
    pub scores: &'a [f32],
    pub distances: &'a [f32],
}

/// NanoDet's boxes: for each cell of each level, the best wanted class at `threshold` or
/// more; each side's distance is the expectation of the softmax over its bins, in strides,
/// measured from the cell's centre ((x + 0.5) · stride).
pub fn nanodet(
    levels: &[Level],
    side: u32,
    classes: usize,
    threshold: f32,
    wanted: impl Fn(usize) -> bool,
) -> Vec<PixelBox> {
    let mut found = vec![];
    for level in levels {
        let across = side.div_ceil(level.stride) as usize;
        let cells = level.scores.len() / classes.max(1);
        if cells == 0 || level.distances.len() % cells != 0 {
            continue;
        }
        let per_side = level.distances.len() / cells / 4;
        for cell in 0..cells {
            let Some((class, confidence)) =
                best(&level.scores[cell * classes..(cell + 1) * classes], &wanted)
            else {
                continue;
            };
            if confidence < threshold {
                continue;
            }
            let stride = level.stride as f64;
            let centre =
                DVec2::new((cell % across) as f64 + 0.5, (cell / across) as f64 + 0.5) * stride;
            let d = &level.distances[cell * 4 * per_side..(cell + 1) * 4 * per_side];
            let [l, t, r, b] = std::array::from_fn(|k| {
                expected_bin(&d[k * per_side..(k + 1) * per_side]) * stride
            });
            found.push(PixelBox {
                low: centre - DVec2::new(l, t),
                high: centre + DVec2::new(r, b),
                confidence,
                class: class as u16,
            });
        }
    }
    found
}

/// YOLOv8's boxes from its one output, `[4 + classes, anchors]` row-major: rows 0..4 the
/// centre x, y and width, height; then one row of scores per class.
pub fn yolov8(
    output: &[f32],
    anchors: usize,
    threshold: f32,
    wanted: impl Fn(usize) -> bool,
) -> Vec<PixelBox> {
    if anchors == 0 || !output.len().is_multiple_of(anchors) || output.len() / anchors <= 4 {
        return vec![];
    }
    let classes = output.len() / anchors - 4;
    let at = |row: usize, a: usize| output[row * anchors + a];
    let mut found = vec![];
    for a in 0..anchors {
        let scores = (0..classes).map(|c| at(4 + c, a));
        let Some((class, confidence)) = scores
            .enumerate()
            .filter(|&(c, s)| wanted(c) && s.is_finite())
            .max_by(|x, y| x.1.total_cmp(&y.1))
        else {
            continue;
        };
        if confidence < threshold {
            continue;
        }
        let centre = DVec2::new(at(0, a) as f64, at(1, a) as f64);
        let half = DVec2::new(at(2, a) as f64, at(3, a) as f64) / 2.0;
        found.push(PixelBox {
            low: centre - half,
            high: centre + half,
            confidence,
            class: class as u16,
        });
    }
    found
}

/// The best-scoring wanted class and its score.
fn best(scores: &[f32], wanted: impl Fn(usize) -> bool) -> Option<(usize, f32)> {
    scores
        .iter()
        .copied()
        .enumerate()
        .filter(|&(c, s)| wanted(c) && s.is_finite())
        .max_by(|a, b| a.1.total_cmp(&b.1))
}

/// The expected bin of a softmax over `logits` (0 ..= len − 1).
fn expected_bin(logits: &[f32]) -> f64 {
    let top = logits.iter().copied().fold(f32::NEG_INFINITY, f32::max);
    let weights: Vec<f64> = logits.iter().map(|&v| ((v - top) as f64).exp()).collect();
    let total: f64 = weights.iter().sum();
    if total.is_nan() || total <= 0.0 {
        return 0.0;
    }
    weights
        .iter()
        .enumerate()
        .map(|(i, w)| i as f64 * w)
        .sum::<f64>()
        / total
}

/// The 80 COCO classes in the order COCO-trained models (NanoDet, YOLOv8) number them.
pub const COCO: [&str; 80] = [
    "person",
    "bicycle",
    "car",
    "motorcycle",
    "airplane",
    "bus",
    "train",
    "truck",
    "boat",
    "traffic light",
    "fire hydrant",
    "stop sign",
    "parking meter",
    "bench",
    "bird",
    "cat",
    "dog",
    "horse",
    "sheep",
    "cow",
    "elephant",
    "bear",
    "zebra",
    "giraffe",
    "backpack",
    "umbrella",
    "handbag",
    "tie",
    "suitcase",
    "frisbee",
    "skis",
    "snowboard",
    "sports ball",
    "kite",
    "baseball bat",
    "baseball glove",
    "skateboard",
    "surfboard",
    "tennis racket",
    "bottle",
    "wine glass",
    "cup",
    "fork",
    "knife",
    "spoon",
    "bowl",
    "banana",
    "apple",
    "sandwich",
    "orange",
    "broccoli",
    "carrot",
    "hot dog",
    "pizza",
    "donut",
    "cake",
    "chair",
    "couch",
    "potted plant",
    "bed",
    "dining table",
    "toilet",
    "tv",
    "laptop",
    "mouse",
    "remote",
    "keyboard",
    "cell phone",
    "microwave",
    "oven",
    "toaster",
    "sink",
    "refrigerator",
    "book",
    "clock",
    "vase",
    "scissors",
    "teddy bear",
    "hair drier",
    "toothbrush",
];

#[cfg(test)]
mod tests {
    use super::*;

    /// Logits with all weight on `bin`.
    fn peaked(bins: usize, bin: usize) -> Vec<f32> {
        (0..bins)
            .map(|i| if i == bin { 30.0 } else { 0.0 })
            .collect()
    }

    #[test]
    fn nanodet_distances_are_expected_bins_times_the_stride_from_the_cell_centre() {
        // A 32-px picture at stride 8: 4 × 4 cells, 2 classes, 3 bins a side.
        let (side, stride, classes, bins) = (32, 8, 2, 3);
        let cells = 16;
        let mut scores = vec![0.0f32; cells * classes];
        let mut distances = vec![0.0f32; cells * 4 * bins];
        // Cell (2, 1): class 1 at 0.8; left 1 bin, top 2, right 0, bottom an even split of
        // bins 0 and 2 (expectation 1).
        let cell = 4 + 2;
        scores[cell * classes + 1] = 0.8;
        scores[cell * classes] = 0.3;
        let sides = [
            peaked(bins, 1),
            peaked(bins, 2),
            peaked(bins, 0),
            vec![5.0, -30.0, 5.0],
        ];
        for (k, s) in sides.iter().enumerate() {
            distances[(cell * 4 + k) * bins..(cell * 4 + k + 1) * bins].copy_from_slice(s);
        }
        let level = Level {
            stride,
            scores: &scores,
            distances: &distances,
        };
        let found = nanodet(&[level], side, classes, 0.5, |_| true);
        assert_eq!(found.len(), 1);
        let b = found[0];
        assert_eq!((b.class, b.confidence), (1, 0.8));
        // Centre (20, 12).
        assert!((b.low - DVec2::new(12.0, -4.0)).length() < 1e-6, "{b:?}");
        assert!((b.high - DVec2::new(20.0, 20.0)).length() < 1e-6, "{b:?}");
        // Class 1 not wanted: class 0 at 0.3 is what the cell has.
        let level = Level {
            stride,
            scores: &scores,
            distances: &distances,
        };
        assert!(nanodet(&[level], side, classes, 0.25, |c| c == 0)[0].class == 0);
    }

    #[test]
    fn yolov8_reads_centre_size_and_the_best_wanted_class() {
        // 3 anchors, 2 classes: rows cx, cy, w, h, class 0, class 1.
        let out = [
            10.0, 50.0, 0.0, //
            20.0, 60.0, 0.0, //
            4.0, 10.0, 0.0, //
            6.0, 20.0, 0.0, //
            0.9, 0.2, 0.0, //
            0.1, 0.7, 0.1, //
        ];
        let found = yolov8(&out, 3, 0.5, |_| true);
        assert_eq!(found.len(), 2);
        assert_eq!(
            (found[0].class, found[0].low, found[0].high),
            (0, DVec2::new(8.0, 17.0), DVec2::new(12.0, 23.0))
        );
        assert_eq!(found[1].class, 1);
        assert!(yolov8(&out, 3, 0.5, |c| c == 1).len() == 1);
        // A malformed output gives nothing, not a panic.
        assert!(yolov8(&out[..7], 3, 0.5, |_| true).is_empty());
        assert!(yolov8(&out, 0, 0.5, |_| true).is_empty());
    }
}
