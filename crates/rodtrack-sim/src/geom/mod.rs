//! The world at one instant as ray-traceable geometry (single precision), and the ray tests:
//! rods (cylinders along `y`), figures (boxes in the rotating rod frame), hands (boxes), the
//! ball (sphere), and the static table (field, lines, walls, floor).

mod ray;
mod shader;
mod table;
mod texture;
mod world;

pub use ray::V3;
pub(crate) use ray::{dot, rod_hit, rod_sample, RodSample};
pub(crate) use shader::{Obj, Shader};
pub(crate) use table::Table;
pub(crate) use world::WorldGeom;
pub use world::{RodPose, WorldState};
