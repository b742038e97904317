//! The two lenses of a pair matched in exposure and colour. Two sensors seldom agree: one
//! may meter brighter, or see a warmer light. Where both see the same rays (the stitch's
//! taps) their means say by how much; each lens is then corrected halfway towards the other
//! (a gain about black for luma and RGB, an offset for 4:2:0 chroma), so a step at the seam
//! becomes none and the picture's overall brightness stays where the two cameras put it. The
//! correction follows the measurement slowly ([`SETTLE`] a frame), so an exposure change
//! shows as a gentle drift, never as a flicker.

use crate::frame::PixelFormat;

/// The share of the distance to each frame's measurement the match moves by (about 20
/// frames, two thirds of a second at 30 fps, to settle).
pub const SETTLE: f64 = 0.05;

/// The most each lens's gain is corrected by, either way: lenses up to four times apart (two
/// stops, as the sun in one lens can make them) are matched; past that, one lens is likely
/// covered or blinded, and matching further would drag the good one towards it.
pub const MOST_GAIN: f64 = 2.0;

/// The most each lens's chroma is moved by, code values.
pub const MOST_OFFSET: f64 = 16.0;

/// How a component is corrected.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Kind {
    /// Scaled about its black (`zero`): RGB about 0, luma about 16.
    Gain { zero: f64 },
    /// Shifted: 4:2:0 chroma (a white balance difference moves it about 128).
    Offset,
}

/// One channel of one plane of the frame, and how it is matched.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Component {
    pub plane: usize,
    pub channel: usize,
    pub kind: Kind,
}

/// The components a format's frames are matched in.
pub fn components(format: PixelFormat) -> Vec<Component> {
    let c = |plane, channel, kind| Component {
        plane,
        channel,
        kind,
    };
    let (luma, chroma) = (Kind::Gain { zero: 16.0 }, Kind::Offset);
    match format {
        PixelFormat::Rgba => (0..3)
            .map(|ch| c(0, ch, Kind::Gain { zero: 0.0 }))
            .collect(),
        PixelFormat::Nv12 => vec![c(0, 0, luma), c(1, 0, chroma), c(1, 1, chroma)],
        PixelFormat::I420 => vec![c(0, 0, luma), c(1, 0, chroma), c(2, 0, chroma)],
    }
}

/// What the match holds between frames: per component, how far the second lens is from the
/// first (the log of the gain ratio, or the offset), smoothed.
#[derive(Clone, Debug, Default)]
pub struct Matching {
    apart: Option<Vec<f64>>,
}

impl Matching {
    /// Takes one frame's means over the overlap (first lens's, second lens's, per
    /// component): the first frame sets the match, later ones move it by [`SETTLE`].
    pub fn update(&mut self, components: &[Component], means: &[(f64, f64)]) {
        let measured: Vec<f64> = components
            .iter()
            .zip(means)
            .map(|(c, &(a, b))| match c.kind {
                Kind::Gain { zero } if a > zero + 1.0 && b > zero + 1.0 => {
                    ((b - zero) / (a - zero)).ln()
                }
                Kind::Gain { .. } => 0.0,
                Kind::Offset => b - a,
            })
            .collect();
        match &mut self.apart {
            Some(apart) if apart.len() == measured.len() => {
                for (x, m) in apart.iter_mut().zip(measured) {
                    *x += SETTLE * (m - *x);
                }
            }
            _ => self.apart = Some(measured),
        }
    }

    /// How far apart the lenses are now: each component's gain ratio (second over first) or
    /// offset (second less first).
    pub fn apart(&self, components: &[Component]) -> Vec<f64> {
        let apart = self.apart.clone().unwrap_or_default();
        components
            .iter()
            .zip(apart.iter().chain(std::iter::repeat(&0.0)))
            .map(|(c, x)| match c.kind {
                Kind::Gain { .. } => x.exp(),
                Kind::Offset => *x,
            })
            .collect()
    }

    /// Each component's tables for the first and the second lens: halfway to each other.
    pub fn tables(&self, components: &[Component]) -> Vec<[[u8; 256]; 2]> {
        let apart = self.apart.clone().unwrap_or_default();
        components
            .iter()
            .zip(apart.iter().chain(std::iter::repeat(&0.0)))
            .map(|(c, &x)| {
                let half = halfway(c.kind, x);
                let table = |half: f64| -> [u8; 256] {
                    std::array::from_fn(|v| {
                        let v = v as f64;
                        let out = match c.kind {
                            Kind::Gain { zero } => zero + (v - zero) * half.exp(),
                            Kind::Offset => v + half,
                        };
                        out.round().clamp(0.0, 255.0) as u8
                    })
                };
                [table(half), table(-half)]
            })
            .collect()
    }

    /// Whether the lenses are further apart than the match corrects ([`MOST_GAIN`],
    /// [`MOST_OFFSET`]) in any component.
    pub fn beyond_reach(&self, components: &[Component]) -> bool {
        let apart = self.apart.clone().unwrap_or_default();
        components
            .iter()
            .zip(&apart)
            .any(|(c, &x)| halfway(c.kind, x) != x / 2.0)
    }
}

/// The correction the first lens takes for lenses `x` apart (the second takes its opposite):
/// half of it, within what the match corrects.
fn halfway(kind: Kind, x: f64) -> f64 {
    let most = match kind {
        Kind::Gain { .. } => MOST_GAIN.ln(),
        Kind::Offset => MOST_OFFSET,
    };
    (x / 2.0).clamp(-most, most)
}
