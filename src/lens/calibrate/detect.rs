//! Finding the board in a frame: the AprilGrid detector (the `aprilgrid` crate, a Rust port of
//! Kalibr's) finds each tag's four corners in the image; here they are matched to their places
//! on the board, in the lens module's pixel convention (OpenCV's: the top-left pixel's centre
//! is (0, 0)).

use super::board::Board;
use aprilgrid::TagFamily;
use aprilgrid::detector::TagDetector;
use glam::DVec2;
use image::DynamicImage;

/// One tag seen in a frame: its corners in the image and on the board, in the same order.
#[derive(Clone, Debug, PartialEq)]
pub struct Sighting {
    pub id: u32,
    pub image: [DVec2; 4],
    pub board: [DVec2; 4],
}

/// Finds a board's tags in frames.
pub struct Finder {
    board: Board,
    detector: TagDetector,
}

impl Finder {
    pub fn new(board: Board) -> Finder {
        Finder {
            board,
            detector: TagDetector::new(&TagFamily::T36H11, None),
        }
    }

    /// Every tag of the board seen in `frame`, by id; ids the board does not have are left out
    /// (another board in view, or a misread).
    pub fn find(&self, frame: &DynamicImage) -> Vec<Sighting> {
        let mut found: Vec<Sighting> = self
            .detector
            .detect(frame)
            .into_iter()
            .filter_map(|(id, corners)| {
                let board = self.board.corners(id)?;
                // The detector lists a tag's corners from its lower-left going
                // anticlockwise on the board, as Kalibr does.
                let image = corners.map(|(x, y)| DVec2::new(x as f64, y as f64));
                Some(Sighting { id, image, board })
            })
            .collect();
        found.sort_by_key(|s| s.id);
        found
    }
}
