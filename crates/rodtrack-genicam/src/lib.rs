//! rodtrack's GenICam camera source: `genicam://ID` inputs through Aravis.
//!
//! Everything here sits behind the crate feature `genicam` (off by default), which pulls in
//! `aravis` and so Aravis' development libraries (see `.ci/genicam.sh`). Without the feature
//! the crate is empty and needs no system library.
