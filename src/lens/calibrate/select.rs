//! Choosing the frames the fit uses when a video gives more than it needs: a video of a board
//! waved before the lens repeats the same view for many frames, and a fit over all of them is
//! slow and weighs the views the camera lingered on. The frames are picked greedily so that
//! every part of the image the board reached is seen, and seen from several frames.

use super::fit::Frame;
use glam::DVec2;

/// Rings (by distance from the frame's centre, out to the farthest corner seen) and sectors
/// (by azimuth) the image is divided into.
const RINGS: usize = 4;
const SECTORS: usize = 12;

/// The cells of the image a frame's corners fall in.
fn cells(frame: &Frame, centre: DVec2, reach: f64) -> Vec<usize> {
    let mut cells: Vec<usize> = frame
        .image
        .iter()
        .map(|q| {
            let d = *q - centre;
            let ring = ((d.length() / reach * RINGS as f64) as usize).min(RINGS - 1);
            let turn = d.y.atan2(d.x).rem_euclid(std::f64::consts::TAU) / std::f64::consts::TAU;
            let sector = ((turn * SECTORS as f64) as usize).min(SECTORS - 1);
            ring * SECTORS + sector
        })
        .collect();
    cells.sort_unstable();
    cells.dedup();
    cells
}

/// At most `most` of `frames` (of a `size` image), in their order: each pick the frame whose
/// cells the frames already picked cover least (a cell picked n times counts 1/(n + 1)), ties
/// going to the frame with more corners.
pub fn spread(frames: &[Frame], size: (u32, u32), most: usize) -> Vec<usize> {
    if frames.len() <= most {
        return (0..frames.len()).collect();
    }
    let centre = DVec2::new(size.0 as f64 - 1.0, size.1 as f64 - 1.0) / 2.0;
    let reach = frames
        .iter()
        .flat_map(|f| &f.image)
        .map(|q| q.distance(centre))
        .fold(1.0, f64::max)
        * (1.0 + 1e-9);
    let seen: Vec<Vec<usize>> = frames.iter().map(|f| cells(f, centre, reach)).collect();
    let mut picked_in = [0u32; RINGS * SECTORS];
    let mut picked = vec![false; frames.len()];
    for _ in 0..most {
        let score = |i: usize| {
            let new: f64 = seen[i]
                .iter()
                .map(|&c| 1.0 / (1.0 + picked_in[c] as f64))
                .sum();
            new + frames[i].image.len() as f64 * 1e-6
        };
        let Some(best) = (0..frames.len())
            .filter(|&i| !picked[i])
            .max_by(|&a, &b| score(a).total_cmp(&score(b)))
        else {
            break;
        };
        picked[best] = true;
        for &c in &seen[best] {
            picked_in[c] += 1;
        }
    }
    (0..frames.len()).filter(|&i| picked[i]).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A frame with corners in a small patch around `at`.
    fn patch(at: DVec2, corners: usize) -> Frame {
        let image = (0..corners)
            .map(|k| at + DVec2::new((k % 4) as f64, (k / 4) as f64))
            .collect();
        Frame {
            board: vec![DVec2::ZERO; corners],
            image,
        }
    }

    #[test]
    fn repeated_views_give_way_to_the_parts_of_the_image_not_yet_seen() {
        let size = (1000, 1000);
        let centre = DVec2::splat(499.5);
        // Thirty frames lingering at the centre (the later ones with more corners), then one
        // frame in each of eight places round the edge.
        let middle = centre + DVec2::splat(20.0);
        let mut frames: Vec<Frame> = (0..30).map(|i| patch(middle, 16 + i)).collect();
        for s in 0..8 {
            let a = s as f64 * std::f64::consts::TAU / 8.0;
            frames.push(patch(centre + DVec2::new(a.cos(), a.sin()) * 450.0, 12));
        }
        let picked = spread(&frames, size, 10);
        assert_eq!(picked.len(), 10);
        // Every edge frame, and two of the lingering ones (the fullest first).
        for i in 30..38 {
            assert!(picked.contains(&i), "{picked:?}");
        }
        assert_eq!(picked.iter().filter(|&&i| i < 30).count(), 2, "{picked:?}");
        assert!(picked.contains(&29), "{picked:?}");
        // Fewer frames than asked for: all of them.
        assert_eq!(spread(&frames[..5], size, 10), vec![0, 1, 2, 3, 4]);
    }
}
