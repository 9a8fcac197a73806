//! The record's fields as columns: the ONE place that reads [`Measurement`]'s fields.
//!
//! Every field the binding exposes is one line of the `columns!` table below: its name, its
//! element type and how it is read from a record. The table makes [`Columns`] (plain vectors,
//! no Python), [`COLUMN_NAMES`] and, with the `python` feature, the `Rows` class whose
//! attributes are numpy arrays (`rows.position_mm`, ...). A field added to the record is one
//! line here (and one in the type stubs, `rodtrack/_rodtrack.pyi`, which a test checks).

use rodtrack_core::ball::{BallRow, BallStatus};
use rodtrack_core::{CameraId, Measurement, Status};

/// The status names by code: `rows.status[i]` is an index into this list.
pub const STATUS_NAMES: [&str; 8] = [
    "ok",
    "not_found",
    "occluded",
    "out_of_view",
    "predicted",
    "lost",
    "bad_frame",
    "conflict",
];

/// The camera code of fused rows in `rows.camera` (camera rows carry the camera's index).
pub const FUSED_CAMERA: i64 = -1;

/// The code of `status`: its index in [`STATUS_NAMES`].
pub fn status_code(status: Status) -> u8 {
    // An exhaustive match: a status added to the core fails to compile here.
    let name = match status {
        Status::Ok
        | Status::NotFound
        | Status::Occluded
        | Status::OutOfView
        | Status::Predicted
        | Status::Lost
        | Status::BadFrame
        | Status::Conflict => status.name(),
    };
    STATUS_NAMES.iter().position(|n| *n == name).unwrap_or(0) as u8
}

/// The camera code of a row: the camera's index, or [`FUSED_CAMERA`].
pub fn camera_code(camera: CameraId) -> i64 {
    match camera {
        CameraId::Camera(i) => i64::from(i),
        CameraId::Fused => FUSED_CAMERA,
    }
}

/// A record's fields as columns: `$cols` (plain vectors), `$names` and, with the `python`
/// feature, the Python class `$py` (named `$pyname`) whose attributes are numpy arrays, its
/// `status` column's names in `$statuses`.
macro_rules! columns {
    (
        $(#[$pydoc:meta])*
        $cols:ident($rec:ty), $names:ident, $py:ident = $pyname:literal, $statuses:path;
        $( $(#[doc = $doc:literal])+ $name:ident : $ty:ty = |$m:ident| $get:expr ;)+
    ) => {
        /// Rows as columns, one vector per field of the names' list, in row order.
        #[derive(Debug, Clone, Default, PartialEq)]
        pub struct $cols {
            $( $(#[doc = $doc])+ pub $name: Vec<$ty>, )+
        }

        /// The column names, in the order of the record (and of the CSV files' columns).
        pub const $names: &[&str] = &[$(stringify!($name)),+];

        impl $cols {
            /// Appends one record.
            pub fn push(&mut self, m: &$rec) {
                $( { let $m = m; self.$name.push($get); } )+
            }

            /// The columns of `rows`.
            pub fn of<'a>(rows: impl IntoIterator<Item = &'a $rec>) -> $cols {
                let mut c = $cols::default();
                for m in rows {
                    c.push(m);
                }
                c
            }

            /// Number of rows.
            pub fn len(&self) -> usize {
                first_len(&[$(self.$name.len()),+])
            }

            /// True when there is no row.
            pub fn is_empty(&self) -> bool {
                self.len() == 0
            }
        }

        $(#[$pydoc])*
        #[cfg(feature = "python")]
        #[pyo3::pyclass(module = "rodtrack", frozen, name = $pyname)]
        pub struct $py {
            /// The rows.
            pub cols: $cols,
        }

        #[cfg(feature = "python")]
        #[pyo3::pymethods]
        impl $py {
            $(
                $(#[doc = $doc])+
                #[getter]
                fn $name<'py>(&self, py: pyo3::Python<'py>) -> pyo3::Bound<'py, numpy::PyArray1<$ty>> {
                    numpy::PyArray1::from_slice(py, &self.cols.$name)
                }
            )+

            /// The status of each row by name (its code's entry in the status names).
            fn status_names(&self) -> Vec<&'static str> {
                self.cols
                    .status
                    .iter()
                    .map(|c| $statuses.get(usize::from(*c)).copied().unwrap_or("?"))
                    .collect()
            }

            /// Number of rows.
            fn __len__(&self) -> usize {
                self.cols.len()
            }

            fn __repr__(&self) -> String {
                format!("{}({} rows: {})", $pyname, self.cols.len(), $names.join(", "))
            }

            /// Every column by name, as numpy arrays.
            fn to_dict<'py>(
                &self,
                py: pyo3::Python<'py>,
            ) -> pyo3::PyResult<pyo3::Bound<'py, pyo3::types::PyDict>> {
                use pyo3::types::PyDictMethods;
                let d = pyo3::types::PyDict::new(py);
                $( d.set_item(stringify!($name), numpy::PyArray1::from_slice(py, &self.cols.$name))?; )+
                Ok(d)
            }
        }
    };
}

fn first_len(lens: &[usize]) -> usize {
    lens.first().copied().unwrap_or(0)
}

columns! {
    /// One tracked frame's (or frame set's) rows, one entry per row in each column: numpy
    /// arrays named like the CSV columns. `camera` is the camera index or -1 (`FUSED`) for
    /// fused rows; `status` a code, an index into `STATUS_NAMES`. Each attribute access
    /// returns a new array (a copy of a few values).
    Columns(Measurement), COLUMN_NAMES, PyRows = "Rows", STATUS_NAMES;
    /// The camera's frame id.
    frame: u64 = |m| m.frame;
    /// Capture time, seconds (``timestamp_ns * 1e-9``, as the CSV prints it).
    timestamp_s: f64 = |m| m.timestamp_s();
    /// Capture time, nanoseconds from the source's epoch: the exact value the record carries.
    timestamp_ns: u64 = |m| m.timestamp_ns.as_nanos();
    /// The camera's index, or -1 (`FUSED`) for fused rows.
    camera: i64 = |m| camera_code(m.camera);
    /// Rod id.
    rod: u32 = |m| m.rod;
    /// Translation along the rod's axis from its calibrated zero, mm.
    position_mm: f64 = |m| m.position_mm;
    /// Rotation about the rod's axis, right-handed, in [0, 2 pi).
    angle_rad: f64 = |m| m.angle_rad;
    /// Rotation counting whole turns, rad.
    angle_unwrapped_rad: f64 = |m| m.angle_unwrapped_rad;
    /// Translation velocity, mm/s (0 when not estimated: raw rows).
    velocity_mm_s: f64 = |m| m.velocity_mm_s;
    /// Angular velocity, rad/s (0 when not estimated: raw rows).
    angular_velocity_rad_s: f64 = |m| m.angular_velocity_rad_s;
    /// Confidence in [0, 1].
    quality: f64 = |m| m.quality;
    /// Whether to trust the values: an index into `STATUS_NAMES` (0 = ok).
    status: u8 = |m| status_code(m.status);
    /// Whether `angle_unwrapped_rad` counts the whole turns for sure (false after a stretch in
    /// which the count could have slipped, until it is re-anchored).
    turns_known: bool = |m| m.turns_known;
}

/// The ball's status names by code: `ball.status[i]` is an index into this list.
pub const BALL_STATUS_NAMES: [&str; 4] = ["ok", "predicted", "lost", "conflict"];

/// The code of a ball row's status: its index in [`BALL_STATUS_NAMES`].
pub fn ball_status_code(status: BallStatus) -> u8 {
    match status {
        BallStatus::Ok => 0,
        BallStatus::Predicted => 1,
        BallStatus::Lost => 2,
        BallStatus::Conflict => 3,
    }
}

columns! {
    /// The ball's rows, one entry per row in each column: numpy arrays named like the columns
    /// of `rodtrack track --ball-out` (the table frame, mm). `camera` is the camera index or
    /// -1 (`FUSED`) for fused rows; `status` a code, an index into `BALL_STATUS_NAMES`.
    BallColumns(BallRow), BALL_COLUMN_NAMES, PyBallRows = "BallRows", BALL_STATUS_NAMES;
    /// The frame id.
    frame: u64 = |b| b.frame;
    /// Capture time, seconds.
    timestamp_s: f64 = |b| b.timestamp_s();
    /// Capture time, nanoseconds from the source's epoch.
    timestamp_ns: u64 = |b| b.timestamp_ns.as_nanos();
    /// The camera's index, or -1 (`FUSED`) for fused rows.
    camera: i64 = |b| camera_code(b.camera);
    /// The ball's centre in the table frame, mm (x towards goal B).
    x_mm: f64 = |b| b.x_mm;
    /// The ball's centre in the table frame, mm (y across the table).
    y_mm: f64 = |b| b.y_mm;
    /// Velocity, mm/s.
    vx_mm_s: f64 = |b| b.vx_mm_s;
    /// Velocity, mm/s.
    vy_mm_s: f64 = |b| b.vy_mm_s;
    /// Fraction of the ball's outline measured, in [0, 1].
    quality: f64 = |b| b.quality;
    /// An index into `BALL_STATUS_NAMES` (0 = ok: measured in this frame; predicted: from the
    /// track, not seen; lost; conflict: the cameras disagree).
    status: u8 = |b| ball_status_code(b.status);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_status_has_its_code_and_name() {
        for (i, name) in STATUS_NAMES.iter().enumerate() {
            let s = Status::from_name(name).expect("a status name of the core");
            assert_eq!(status_code(s) as usize, i, "{name}");
        }
    }

    #[test]
    fn the_ball_columns_follow_the_ball_csv() {
        for (i, name) in BALL_STATUS_NAMES.iter().enumerate() {
            let s = BallStatus::from_name(name).expect("a ball status of the core");
            assert_eq!(ball_status_code(s) as usize, i, "{name}");
        }
        // frame,timestamp_s,camera,x_mm,y_mm,vx_mm_s,vy_mm_s,quality,status
        for c in BallRow::CSV_HEADER.split(',') {
            assert!(BALL_COLUMN_NAMES.contains(&c), "ball column {c} missing");
        }
        let mut b = BallRow::lost(9, rodtrack_core::Timestamp(45_000_000), CameraId::Camera(1));
        b.x_mm = 12.5;
        let c = BallColumns::of([&b]);
        assert_eq!((c.frame[0], c.camera[0], c.x_mm[0]), (9, 1, 12.5));
        assert_eq!(c.timestamp_s, [45_000_000.0 * 1e-9]);
        assert_eq!(c.status, [2]);
    }

    #[test]
    fn the_columns_follow_the_csv_columns() {
        // The CSV's columns are the record's; the binding exposes each of them by its name.
        for c in rodtrack_core::measurement::CSV_COLUMNS {
            assert!(
                COLUMN_NAMES.contains(&c),
                "column {c} missing from the binding"
            );
        }
        let mut m = Measurement::empty(
            7,
            rodtrack_core::Timestamp(35_000_000),
            CameraId::Fused,
            3,
            Status::Occluded,
        );
        m.position_mm = -12.5;
        let c = Columns::of([&m, &m]);
        assert_eq!(c.len(), 2);
        assert_eq!(c.frame, [7, 7]);
        assert_eq!(c.timestamp_ns, [35_000_000; 2]);
        assert_eq!(c.timestamp_s, [0.035; 2]);
        assert_eq!(c.camera, [FUSED_CAMERA; 2]);
        assert_eq!(c.position_mm, [-12.5; 2]);
        assert_eq!(c.status, [2, 2]);
    }
}
