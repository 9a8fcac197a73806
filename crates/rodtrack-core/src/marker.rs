//! The marker (SPEC section 3): a barcode of full rings and a Gray-code section, wrapped once
//! around the rod.
//!
//! Coordinates on the marker: `u_mm` along the rod from the marker's start, pointing from the
//! barcode towards the Gray code; `psi_rad` around the rod, in `[0, 2 pi)`. At rod angle
//! `theta`, the surface line facing the camera reads `gray(floor(32 theta / 2 pi))` plus a
//! per-rod constant that calibration removes.

use crate::angle::wrap_2pi;
use crate::CoreError;
use serde::{Deserialize, Serialize};
use std::f64::consts::TAU;

/// The barcode part of a marker.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BarcodeSpec {
    /// Where the first cell starts, mm from the marker's start.
    pub start_mm: f64,
    /// Length of one cell along the rod, mm.
    pub cell_mm: f64,
    /// Cell colours, bit 0 first: `1` is black.
    pub kernel: String,
}

/// The Gray-code part of a marker.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GrayCodeSpec {
    /// Where bit space 0 starts, mm from the marker's start.
    pub start_mm: f64,
    /// Length of one bit space along the rod, mm.
    pub bit_space_mm: f64,
    /// Number of bit spaces (bits of the code).
    pub bits: u32,
}

/// A marker description (the "marker description file"). Defaults are marker v1.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MarkerSpec {
    /// Diameter of the rod the marker is wrapped around, mm.
    pub rod_diameter_mm: f64,
    /// The barcode.
    pub barcode: BarcodeSpec,
    /// The Gray code.
    pub gray_code: GrayCodeSpec,
    /// Total printed length, mm; by default the Gray code's end plus a 4 mm quiet zone.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub length_mm: Option<f64>,
}

impl Default for MarkerSpec {
    fn default() -> Self {
        MarkerSpec {
            rod_diameter_mm: 16.0,
            barcode: BarcodeSpec {
                start_mm: 4.0,
                cell_mm: 4.0,
                kernel: "1001101010000101".to_string(),
            },
            gray_code: GrayCodeSpec {
                start_mm: 72.0,
                bit_space_mm: 6.0,
                bits: 5,
            },
            length_mm: None,
        }
    }
}

/// A validated marker with its kernel unpacked, ready for computation.
#[derive(Debug, Clone, PartialEq)]
pub struct Marker {
    spec: MarkerSpec,
    kernel: Vec<bool>,
}

impl MarkerSpec {
    /// Checks every parameter; the error names the field.
    pub fn validate(&self) -> Result<Marker, CoreError> {
        let bad = |field: &'static str, reason: String| CoreError::Marker { field, reason };
        let finite_pos = |field: &'static str, v: f64| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(bad(field, format!("must be a positive number, got {v}")))
            }
        };
        finite_pos("rod_diameter_mm", self.rod_diameter_mm)?;
        finite_pos("barcode.cell_mm", self.barcode.cell_mm)?;
        finite_pos("gray_code.bit_space_mm", self.gray_code.bit_space_mm)?;
        if !(self.barcode.start_mm.is_finite() && self.barcode.start_mm >= 0.0) {
            return Err(bad(
                "barcode.start_mm",
                format!("must be >= 0, got {}", self.barcode.start_mm),
            ));
        }
        let kernel: Vec<bool> = self
            .barcode
            .kernel
            .chars()
            .map(|c| match c {
                '0' => Ok(false),
                '1' => Ok(true),
                other => Err(bad(
                    "barcode.kernel",
                    format!("may hold only '0' and '1', found {other:?}"),
                )),
            })
            .collect::<Result<_, _>>()?;
        if kernel.len() < 4 || kernel.len() > 64 {
            return Err(bad(
                "barcode.kernel",
                format!("must have 4 to 64 cells, has {}", kernel.len()),
            ));
        }
        let ones = kernel.iter().filter(|b| **b).count();
        if ones == 0 || ones == kernel.len() {
            return Err(bad(
                "barcode.kernel",
                "must hold both black (1) and white (0) cells".to_string(),
            ));
        }
        let rev: Vec<bool> = kernel.iter().rev().copied().collect();
        if rev == kernel {
            return Err(bad(
                "barcode.kernel",
                "must not read the same backwards, or the marker's direction is ambiguous"
                    .to_string(),
            ));
        }
        if !(1..=8).contains(&self.gray_code.bits) {
            return Err(bad(
                "gray_code.bits",
                format!("must be 1 to 8, got {}", self.gray_code.bits),
            ));
        }
        if self.gray_code.bits < 3 {
            return Err(bad(
                "gray_code.bits",
                "must be at least 3: the phase replaces the two lowest bits".to_string(),
            ));
        }
        let barcode_end = self.barcode.start_mm + kernel.len() as f64 * self.barcode.cell_mm;
        if !(self.gray_code.start_mm.is_finite() && self.gray_code.start_mm >= barcode_end) {
            return Err(bad(
                "gray_code.start_mm",
                format!(
                    "must be at or after the barcode's end ({barcode_end} mm), got {}",
                    self.gray_code.start_mm
                ),
            ));
        }
        let gray_end =
            self.gray_code.start_mm + self.gray_code.bits as f64 * self.gray_code.bit_space_mm;
        if let Some(len) = self.length_mm {
            if !(len.is_finite() && len >= gray_end) {
                return Err(bad(
                    "length_mm",
                    format!("must be at least the Gray code's end ({gray_end} mm), got {len}"),
                ));
            }
        }
        Ok(Marker {
            spec: self.clone(),
            kernel,
        })
    }
}

impl Marker {
    /// Marker v1.
    pub fn v1() -> Marker {
        // The default is valid by construction; the test suite checks it.
        match MarkerSpec::default().validate() {
            Ok(m) => m,
            Err(e) => unreachable!("marker v1 is invalid: {e}"),
        }
    }
    /// The description this marker was made from.
    pub fn spec(&self) -> &MarkerSpec {
        &self.spec
    }
    /// Kernel cells, bit 0 first; `true` is black.
    pub fn kernel(&self) -> &[bool] {
        &self.kernel
    }
    /// Rod radius, mm.
    pub fn radius_mm(&self) -> f64 {
        self.spec.rod_diameter_mm * 0.5
    }
    /// Barcode start, mm from the marker's start.
    pub fn barcode_start_mm(&self) -> f64 {
        self.spec.barcode.start_mm
    }
    /// Cell length, mm.
    pub fn cell_mm(&self) -> f64 {
        self.spec.barcode.cell_mm
    }
    /// Barcode length, mm.
    pub fn barcode_len_mm(&self) -> f64 {
        self.kernel.len() as f64 * self.spec.barcode.cell_mm
    }
    /// Number of Gray bits.
    pub fn bits(&self) -> u32 {
        self.spec.gray_code.bits
    }
    /// Number of Gray steps around the rod (`2^bits`).
    pub fn steps(&self) -> u32 {
        1 << self.spec.gray_code.bits
    }
    /// Centre of bit space `k` along the rod, mm from the marker's start.
    pub fn bit_space_centre_mm(&self, k: u32) -> f64 {
        self.spec.gray_code.start_mm + (k as f64 + 0.5) * self.spec.gray_code.bit_space_mm
    }
    /// Bit space length, mm.
    pub fn bit_space_mm(&self) -> f64 {
        self.spec.gray_code.bit_space_mm
    }
    /// Gray code start, mm.
    pub fn gray_start_mm(&self) -> f64 {
        self.spec.gray_code.start_mm
    }
    /// Total printed length, mm.
    pub fn length_mm(&self) -> f64 {
        self.spec.length_mm.unwrap_or(
            self.spec.gray_code.start_mm
                + self.spec.gray_code.bits as f64 * self.spec.gray_code.bit_space_mm
                + 4.0,
        )
    }
    /// Positions of the barcode's black/white edges, mm from the marker's start, with `true`
    /// for a white-to-black edge (in the `u` direction). The outer edges of the first and last
    /// cell count when those cells are black (the quiet zones are white).
    pub fn barcode_edges_mm(&self) -> Vec<(f64, bool)> {
        let mut edges = Vec::new();
        let mut prev = false;
        for (i, &b) in self.kernel.iter().enumerate() {
            if b != prev {
                edges.push((self.barcode_start_mm() + i as f64 * self.cell_mm(), b));
            }
            prev = b;
        }
        if prev {
            edges.push((self.barcode_start_mm() + self.barcode_len_mm(), false));
        }
        edges
    }

    /// Which Gray step a print angle falls into: `floor(steps * psi / 2 pi)`.
    pub fn step_of(&self, psi_rad: f64) -> u32 {
        let s = self.steps();
        let n = (wrap_2pi(psi_rad) / TAU * s as f64).floor() as u32;
        n.min(s - 1)
    }

    /// True where the print is black at `(u_mm, psi_rad)`. Outside the barcode and the Gray
    /// bit spaces the print is white. The simulator samples this; the generated SVG draws it.
    pub fn is_black(&self, u_mm: f64, psi_rad: f64) -> bool {
        let bc0 = self.barcode_start_mm();
        if u_mm >= bc0 && u_mm < bc0 + self.barcode_len_mm() {
            let i = ((u_mm - bc0) / self.cell_mm()).floor() as usize;
            return self.kernel[i.min(self.kernel.len() - 1)];
        }
        let g0 = self.gray_start_mm();
        let g1 = g0 + self.bits() as f64 * self.bit_space_mm();
        if u_mm >= g0 && u_mm < g1 {
            let k = (((u_mm - g0) / self.bit_space_mm()).floor() as u32).min(self.bits() - 1);
            return gray_bit(self.step_of(psi_rad), k);
        }
        false
    }
}

/// Gray code of `n`: `n ^ (n >> 1)`.
pub fn gray(n: u32) -> u32 {
    n ^ (n >> 1)
}

/// Bit `k` of `gray(n)`: black in bit space `k` at step `n`.
pub fn gray_bit(n: u32, k: u32) -> bool {
    (gray(n) >> k) & 1 == 1
}

/// Inverse of [`gray`].
pub fn gray_decode(code: u32) -> u32 {
    let mut n = code;
    let mut shift = code >> 1;
    while shift != 0 {
        n ^= shift;
        shift >>= 1;
    }
    n
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn v1_matches_spec() {
        let m = Marker::v1();
        assert_eq!(m.kernel().len(), 16);
        assert_eq!(m.length_mm(), 106.0);
        assert_eq!(m.barcode_len_mm(), 64.0);
        let edges = m.barcode_edges_mm();
        assert_eq!(edges.len(), 12, "6 black bars have 12 edges");
        assert_eq!(edges[0], (4.0, true));
        assert_eq!(edges[11], (68.0, false));
        assert_eq!(m.bit_space_centre_mm(0), 75.0);
        assert_eq!(m.bit_space_centre_mm(4), 99.0);
    }

    #[test]
    fn bit_space_stripe_counts() {
        // Bit space 0 holds 8 black and 8 white stripes; 3 and 4 one of each.
        let m = Marker::v1();
        for (k, blacks) in [(0u32, 8usize), (1, 4), (2, 2), (3, 1), (4, 1)] {
            let mut runs = 0;
            let mut prev = m.is_black(m.bit_space_centre_mm(k), TAU - 1e-9);
            for i in 0..3200 {
                let b = m.is_black(m.bit_space_centre_mm(k), i as f64 / 3200.0 * TAU);
                if b && !prev {
                    runs += 1;
                }
                prev = b;
            }
            assert_eq!(runs, blacks, "bit space {k}");
        }
    }

    #[test]
    fn validation_names_the_field() {
        let mut s = MarkerSpec::default();
        s.barcode.kernel = "10x1".into();
        let e = s.validate().unwrap_err().to_string();
        assert!(e.contains("barcode.kernel"), "{e}");
        let mut s = MarkerSpec::default();
        s.barcode.kernel = "1001".into();
        assert!(s.validate().unwrap_err().to_string().contains("backwards"));
        let s = MarkerSpec {
            rod_diameter_mm: f64::NAN,
            ..MarkerSpec::default()
        };
        assert!(s
            .validate()
            .unwrap_err()
            .to_string()
            .contains("rod_diameter_mm"));
        let mut s = MarkerSpec::default();
        s.gray_code.start_mm = 50.0;
        assert!(s
            .validate()
            .unwrap_err()
            .to_string()
            .contains("gray_code.start_mm"));
    }

    proptest! {
        #[test]
        fn gray_round_trip(n in 0u32..1_000_000) {
            prop_assert_eq!(gray_decode(gray(n)), n);
        }
        #[test]
        fn gray_neighbours_differ_in_one_bit(n in 0u32..31) {
            prop_assert_eq!((gray(n) ^ gray(n + 1)).count_ones(), 1);
        }
    }

    /// The paper's Table 2, all 32 rows: code (bit 4 first) -> alpha.
    #[test]
    fn paper_table_2() {
        let table = [
            ("00000", 0),
            ("00001", 1),
            ("00011", 2),
            ("00010", 3),
            ("00110", 4),
            ("00111", 5),
            ("00101", 6),
            ("00100", 7),
            ("01100", 8),
            ("01101", 9),
            ("01111", 10),
            ("01110", 11),
            ("01010", 12),
            ("01011", 13),
            ("01001", 14),
            ("01000", 15),
            ("11000", 16),
            ("11001", 17),
            ("11011", 18),
            ("11010", 19),
            ("11110", 20),
            ("11111", 21),
            ("11101", 22),
            ("11100", 23),
            ("10100", 24),
            ("10101", 25),
            ("10111", 26),
            ("10110", 27),
            ("10010", 28),
            ("10011", 29),
            ("10001", 30),
            ("10000", 31),
        ];
        for (code, alpha) in table {
            let c = u32::from_str_radix(code, 2).unwrap();
            assert_eq!(gray_decode(c), alpha, "code {code}");
            assert_eq!(gray(alpha), c);
        }
    }
}
