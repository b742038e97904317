//! The thermal palettes: each a few colours at stops from the coldest level (0) to the
//! hottest (1), drawn into a table of 256 colours by straight lines between the stops (in the
//! sRGB values themselves, as the cores' own palettes are tables of such values).

use super::ThermalError;

/// A palette, by the name users know it by (a file may give its number, THERMAL's).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case", try_from = "NameOrCode")]
pub enum Palette {
    /// Black to white: hot is bright.
    #[default]
    WhiteHot,
    /// White to black: hot is dark.
    BlackHot,
    /// Black through violet, red and orange to yellow and white.
    Ironbow,
    /// Blue through cyan, green, yellow and red to white.
    Rainbow,
    /// Cold in blues, hot in golds.
    Arctic,
    /// Dark through teal and deep red to orange, yellow and white.
    Lava,
}

type Stops = &'static [(f64, [u8; 3])];

impl Palette {
    pub const ALL: [Palette; 6] = [
        Palette::WhiteHot,
        Palette::BlackHot,
        Palette::Ironbow,
        Palette::Rainbow,
        Palette::Arctic,
        Palette::Lava,
    ];

    /// Its number on the wire (THERMAL's palette): its place in [`Palette::ALL`].
    pub fn code(self) -> u8 {
        Palette::ALL.iter().position(|&p| p == self).unwrap_or(0) as u8
    }

    pub fn name(self) -> &'static str {
        match self {
            Palette::WhiteHot => "white-hot",
            Palette::BlackHot => "black-hot",
            Palette::Ironbow => "ironbow",
            Palette::Rainbow => "rainbow",
            Palette::Arctic => "arctic",
            Palette::Lava => "lava",
        }
    }

    fn stops(self) -> Stops {
        match self {
            Palette::WhiteHot => &[(0.0, [0, 0, 0]), (1.0, [255, 255, 255])],
            Palette::BlackHot => &[(0.0, [255, 255, 255]), (1.0, [0, 0, 0])],
            Palette::Ironbow => &[
                (0.0, [0, 0, 0]),
                (0.15, [32, 0, 110]),
                (0.35, [150, 0, 150]),
                (0.55, [225, 60, 30]),
                (0.75, [250, 160, 0]),
                (0.9, [255, 225, 50]),
                (1.0, [255, 255, 230]),
            ],
            Palette::Rainbow => &[
                (0.0, [0, 0, 130]),
                (0.15, [0, 0, 255]),
                (0.3, [0, 200, 255]),
                (0.45, [0, 220, 0]),
                (0.6, [255, 255, 0]),
                (0.75, [255, 120, 0]),
                (0.85, [255, 0, 0]),
                (1.0, [255, 255, 255]),
            ],
            Palette::Arctic => &[
                (0.0, [0, 0, 40]),
                (0.3, [0, 60, 160]),
                (0.5, [60, 160, 220]),
                (0.6, [200, 220, 235]),
                (0.75, [240, 190, 0]),
                (1.0, [255, 255, 200]),
            ],
            Palette::Lava => &[
                (0.0, [10, 10, 30]),
                (0.3, [30, 90, 110]),
                (0.5, [150, 20, 20]),
                (0.7, [240, 80, 0]),
                (0.85, [255, 200, 0]),
                (1.0, [255, 255, 255]),
            ],
        }
    }

    /// The 256 colours of the levels, opaque RGBA.
    pub fn table(self) -> [[u8; 4]; 256] {
        let stops = self.stops();
        std::array::from_fn(|level| {
            let t = level as f64 / 255.0;
            let i = stops
                .iter()
                .rposition(|s| s.0 <= t)
                .unwrap_or(0)
                .min(stops.len() - 2);
            let ((t0, a), (t1, b)) = (stops[i], stops[i + 1]);
            let f = ((t - t0) / (t1 - t0)).clamp(0.0, 1.0);
            let mix = |k: usize| (a[k] as f64 + (b[k] as f64 - a[k] as f64) * f).round() as u8;
            [mix(0), mix(1), mix(2), 255]
        })
    }
}

/// A palette as a file gives it: its name or its number.
#[derive(serde::Deserialize)]
#[serde(untagged)]
pub enum NameOrCode {
    Code(u8),
    Name(String),
}

impl TryFrom<NameOrCode> for Palette {
    type Error = String;

    fn try_from(v: NameOrCode) -> Result<Palette, String> {
        match v {
            NameOrCode::Code(n) => Palette::try_from(n).map_err(|e| e.to_string()),
            NameOrCode::Name(s) => s.parse().map_err(|e: ThermalError| e.to_string()),
        }
    }
}

impl TryFrom<u8> for Palette {
    type Error = crate::modes::NotAMode;

    fn try_from(v: u8) -> Result<Palette, Self::Error> {
        Palette::ALL
            .get(v as usize)
            .copied()
            .ok_or(crate::modes::NotAMode {
                what: "thermal palette",
                value: v,
                top: Palette::ALL.len() as u8 - 1,
            })
    }
}

impl std::str::FromStr for Palette {
    type Err = ThermalError;

    /// A palette by its name, with or without the hyphen, in any case (`ironbow`,
    /// `white-hot`, `WhiteHot`).
    fn from_str(s: &str) -> Result<Palette, ThermalError> {
        let plain = |n: &str| n.replace(['-', '_', ' '], "").to_ascii_lowercase();
        Palette::ALL
            .into_iter()
            .find(|p| plain(p.name()) == plain(s))
            .ok_or_else(|| {
                let names: Vec<&str> = Palette::ALL.iter().map(|p| p.name()).collect();
                ThermalError::Palette(s.to_string(), names.join(", "))
            })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_palette_runs_from_its_first_stop_to_its_last_and_hot_differs_from_cold() {
        for p in Palette::ALL {
            let t = p.table();
            let stops = p.stops();
            assert_eq!(t[0][..3], stops[0].1, "{}", p.name());
            assert_eq!(t[255][..3], stops[stops.len() - 1].1, "{}", p.name());
            assert!(t.iter().all(|c| c[3] == 255));
            // Neighbouring levels never jump (a palette is smooth).
            for w in t.windows(2) {
                let d = (0..3).map(|k| w[0][k].abs_diff(w[1][k])).max().unwrap();
                assert!(d <= 8, "{}: a jump of {d}", p.name());
            }
        }
        let white = Palette::WhiteHot.table();
        assert_eq!(
            (white[0], white[128], white[255]),
            ([0, 0, 0, 255], [128, 128, 128, 255], [255; 4])
        );
    }

    #[test]
    fn names_read_as_users_write_them_and_a_wrong_one_lists_the_right_ones() {
        assert_eq!("ironbow".parse::<Palette>().unwrap(), Palette::Ironbow);
        assert_eq!("WhiteHot".parse::<Palette>().unwrap(), Palette::WhiteHot);
        assert_eq!("black_hot".parse::<Palette>().unwrap(), Palette::BlackHot);
        for p in Palette::ALL {
            assert_eq!(Palette::try_from(p.code()), Ok(p));
        }
        assert_eq!(
            Palette::try_from(6).unwrap_err().to_string(),
            "thermal palette 6 is outside 0..=5"
        );
        let e = "iron".parse::<Palette>().unwrap_err().to_string();
        assert!(
            e.contains("\"iron\"") && e.contains("white-hot, black-hot, ironbow"),
            "{e}"
        );
    }
}
