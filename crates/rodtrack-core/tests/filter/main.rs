//! The temporal filter and the camera fusion on synthetic measurement sequences: a known
//! trajectory, Gaussian noise from a fixed-seed generator, dropped frames, occlusions and the
//! decoder's typical gross errors (a stripe period pi/4, a Gray step 2 pi/32, a barcode cell).
//!
//! `support` makes the sequences and scores them; `temporal` tests one rod's filter, `fusion`
//! the fusion of several cameras' rows.
#![allow(clippy::unwrap_used, missing_docs)]

#[path = "../common/mod.rs"]
mod common;

mod fusion;
mod support;
mod temporal;
