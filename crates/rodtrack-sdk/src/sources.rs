//! The frame sources of this build, by URI.
//!
//! ```
//! let source = rodtrack_sdk::source_factory()
//!     .open("sim://exp3?camera=1&frames=1", &Default::default())
//!     .unwrap();
//! assert!(!source.info().live);
//! ```

use rodtrack_io::SourceFactory;

/// A factory with every source of this build: image folders, `raw:` files and the simulator
/// (`sim://`) always; `video:` files and `genicam://` cameras with the `video` and `genicam`
/// features.
///
/// ```
/// let factory = rodtrack_sdk::source_factory();
/// let source = factory.open("sim://exp3?camera=0&frames=2", &Default::default()).unwrap();
/// assert_eq!(source.info().frame_count, Some(2));
/// ```
pub fn source_factory() -> SourceFactory {
    let mut factory = SourceFactory::new();
    rodtrack_sim::register_sim_source(&mut factory);
    #[cfg(feature = "video")]
    rodtrack_video::register(&mut factory);
    #[cfg(feature = "genicam")]
    rodtrack_genicam::register(&mut factory);
    factory
}
