//! rodtrack's camera network on zenoh: camera nodes publish their rows, a fusion node fuses
//! them as an in-process session would and publishes the fused rows.
//!
//! Everything here sits behind the crate feature `zenoh` (off by default), which pulls in the
//! `zenoh` crate (TCP and UDP transports only); without it the crate is empty, so the default
//! build does not compile zenoh.
//!
//! Key expressions (`<table>`: `--table`, default `default`; `<camera>`: the camera's name in
//! the calibration):
//!
//! | key | what | encoding |
//! |---|---|---|
//! | `rodtrack/<table>/cam/<camera>/rows` | the camera's rows through its temporal filter, one message per frame | `layout` (binary or JSON) |
//! | `rodtrack/<table>/cam/<camera>/raw` | the camera's measured rows, the fusion's input; an `end` message when its run ends | `layout` |
//! | `rodtrack/<table>/cam/<camera>/status` | the camera node's counters, once a second | JSON |
//! | `rodtrack/<table>/cam/<camera>/preview` | a downscaled image of the camera's latest frame, a few per second (`--preview-fps`) | `preview` |
//! | `rodtrack/<table>/cam/<camera>/ball` | the camera's ball rows with their uncertainty, one message per frame (`track --zenoh-ball`) | `ball_layout` |
//! | `rodtrack/<table>/fused/rows` | the fused rows of each frame set, with the set's completeness | `layout` |
//! | `rodtrack/<table>/fused/ball` | each frame's ball rows: the cameras' and the fused one | `ball_layout` |
//! | `rodtrack/<table>/fused/status` | the fusion node's counters and each camera's state, once a second | JSON |
//! | `<domain>/rodtrack/<table>/joint_states/sensor_msgs::msg::dds_::JointState_/RIHS01_...` | the fused rods for ROS 2 over rmw_zenoh (`fuse --ros2-domain`), with rmw_zenoh's attachment and liveliness tokens | CDR (`ros2`) |
//! | `<domain>/rodtrack/<table>/cam/<camera>/joint_states/...` (the same type and hash) | a camera node's rods for ROS 2 over rmw_zenoh (`track --publish zenoh --ros2-domain`) | CDR (`ros2`) |
//! | `<domain>/rodtrack/<table>/ball/geometry_msgs::msg::dds_::PointStamped_/RIHS01_...` | the fused ball's centre for ROS 2 (`fuse --ros2-domain`, a calibration with a ball); a camera node's on `.../cam/<camera>/ball/...` (`--zenoh-ball`) | CDR (`ros2`) |
//! | `<domain>/rodtrack/<table>/ball/velocity/geometry_msgs::msg::dds_::Vector3Stamped_/RIHS01_...` | the fused ball's velocity for ROS 2; a camera node's on `.../cam/<camera>/ball/velocity/...` | CDR (`ros2`) |
//!
//! Layout:
//! - `layout`: the messages (binary layout version 1 and its JSON variant), no zenoh in it;
//! - `ball_layout`: the ball's messages (the same, for ball rows), no zenoh in it;
//! - `net`: the zenoh session from the command line's endpoints or a zenoh config file, the
//!   key expressions, publishing;
//! - `camera`: a camera node (a sink and hooks for an SDK `Session`);
//! - `fusion`: the fusion node (the runtime pipeline over the cameras' messages, with the
//!   same filters and fusion as an in-process session);
//! - `preview`: the preview frames' layout (versioned binary), no zenoh in it;
//! - `monitor`: a remote console's subscriber to every node of a table (rows, statuses,
//!   previews), decoded, malformed messages counted;
//! - `replay`: an MCAP recording's rows published again in real time, on the same keys;
//! - `ros2`: the fused rows as ROS 2 `sensor_msgs/msg/JointState` and the ball as
//!   `geometry_msgs/msg/PointStamped` and `Vector3Stamped` over rmw_zenoh (their key
//!   expressions, attachments and liveliness tokens);
//! - `subscriber`: a program's subscriber to the rows (the fused rows of a table), decoded
//!   (the example `fused_subscriber` prints each rod's fused position through it).

#[cfg(feature = "zenoh")]
pub mod ball_layout;
#[cfg(feature = "zenoh")]
pub mod camera;
#[cfg(feature = "zenoh")]
mod camera_preview;
#[cfg(feature = "zenoh")]
mod error;
#[cfg(feature = "zenoh")]
pub mod fusion;
#[cfg(feature = "zenoh")]
pub mod layout;
#[cfg(feature = "zenoh")]
pub mod monitor;
#[cfg(feature = "zenoh")]
pub mod net;
#[cfg(feature = "zenoh")]
pub mod preview;
#[cfg(feature = "zenoh")]
pub mod replay;
#[cfg(feature = "zenoh")]
pub mod ros2;
#[cfg(feature = "zenoh")]
pub mod subscriber;

#[cfg(feature = "zenoh")]
pub use error::ZenohError;
#[cfg(feature = "zenoh")]
pub use zenoh;
