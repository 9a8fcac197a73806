//! rodtrack's GenICam camera source: `genicam://ID?...` inputs through Aravis.
//!
//! Everything here sits behind the crate feature `genicam` (off by default), which pulls in
//! `aravis` and so Aravis' development libraries (Debian: `libaravis-dev libusb-1.0-0-dev
//! pkg-config`, see `.ci/genicam.sh`). Without the feature the crate is empty and needs no
//! system library, so a plain `cargo test --workspace` works on a fresh machine.
//!
//! Layout:
//! - `GenicamSource` (module `source`): a [`rodtrack_io::FrameSource`] over one camera:
//!   open by id / serial / `first`, explicit configuration, a pool of stream buffers, frame ids
//!   extended to `u64`, counters (`GenicamStats`), reconnection with backoff;
//! - `GenicamOptions` (module `options`): the `genicam://ID?format=BayerRG8|Mono8&width=..
//!   &height=..&offset_x=..&offset_y=..&exposure_us=..&gain=..&fps=..&trigger=free|software|
//!   line0&packet_size=..&buffers=..&timeout_ms=..&give_up_s=..&timestamps=camera|host&sync=NAME`
//!   parameters;
//! - `TriggerClock` (module `clock`): software-triggered groups whose frames share ids;
//! - module `ids`: 16-bit GigE frame ids extended to a monotonic `u64`;
//! - module `ffi`: the only `unsafe` code (device list with serials, the in-process fake
//!   interface, a borrowed view of a buffer's bytes);
//! - `register`, `list_cameras`: for the command line.
//!
//! Synchronised cameras: with hardware, one master in free run drives the others' `Line0`
//! (`trigger=line0` on the slaves; their frame ids then count the same pulses). Without it
//! (and on Aravis' fake cameras, which only do free run and software triggers), give the
//! cameras `trigger=software&fps=F&sync=NAME`: they share one `TriggerClock`, each capture
//! thread fires its camera at every tick, and a frame's id is its tick number, so grouping by
//! frame id gives synchronised sets.

#[cfg(feature = "genicam")]
mod clock;
#[cfg(feature = "genicam")]
mod ffi;
#[cfg(feature = "genicam")]
mod ids;
#[cfg(feature = "genicam")]
mod options;
#[cfg(feature = "genicam")]
mod source;

#[cfg(feature = "genicam")]
pub use clock::{group_clock, TriggerClock};
#[cfg(feature = "genicam")]
pub use ffi::{enable_fake_interface, CameraInfo};
#[cfg(feature = "genicam")]
pub use options::{GenicamOptions, TimestampSource, Trigger};
#[cfg(feature = "genicam")]
pub use source::{
    list_cameras, open_input, register, CameraStatus, GenicamCounters, GenicamSource, GenicamStats,
};
