//! rodtrack for Python: the native module `rodtrack._rodtrack`, built by maturin with the
//! feature `python` (see `pyproject.toml`; `docs/python.md` for the API and the numbers).
//!
//! It sits on the SDK ([`rodtrack_sdk::Session`], calibration files and inputs, the sources)
//! and the core ([`rodtrack_core::CameraPipeline`], the temporal filter, the record), like any
//! other program. Without the feature this crate holds only the parts that need no Python, so
//! that the workspace's default build and tests need neither PyO3 nor an interpreter:
//!
//! - [`columns`]: the record's fields as columns, read in one place;
//! - [`layout`]: an array's memory checked against a camera's frame (borrowed, strides honoured);
//! - [`stream`]: a session in a background thread behind a bounded channel.

pub mod columns;
pub mod layout;
pub mod stream;

#[cfg(feature = "python")]
mod py;
