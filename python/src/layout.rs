//! How an array's memory (shape, strides in bytes, element size) maps onto a camera frame:
//! checked once per call, before any pixel is read, so that a frame is borrowed without a
//! copy and a layout that does not fit is refused with a message that says what to pass.

use rodtrack_core::PixelFormat;

/// An array's layout, as numpy describes it.
#[derive(Debug, Clone, Copy)]
pub struct ArrayLayout<'a> {
    /// The element type's name (`uint8`), for messages.
    pub dtype: &'a str,
    /// Bytes per element.
    pub itemsize: usize,
    /// Elements per dimension.
    pub shape: &'a [usize],
    /// Bytes between neighbours per dimension (negative for reversed views).
    pub strides: &'a [isize],
}

/// A frame's place in an array's memory, in bytes from the first element.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FrameLayout {
    /// Pixels per row.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// Bytes from one row's start to the next's.
    pub stride_bytes: usize,
    /// Bytes from the first pixel to the end of the last row's pixels.
    pub len_bytes: usize,
}

/// Why an array cannot be a camera's frame.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum LayoutError {
    /// The element type does not fit the camera's pixel format.
    #[error("{camera} is calibrated for {format} frames: give a {expected} array, got {got}")]
    Dtype {
        /// `camera 0 (cam0)`.
        camera: String,
        /// The calibration's pixel format.
        format: PixelFormat,
        /// The element type wanted.
        expected: &'static str,
        /// The element type given.
        got: String,
    },
    /// The shape does not fit the camera's image size or pixel format.
    #[error("{camera} is calibrated for {format} frames of shape {expected}: got shape {got}")]
    Shape {
        /// `camera 0 (cam0)`.
        camera: String,
        /// The calibration's pixel format.
        format: PixelFormat,
        /// The shape wanted, `(1080, 1440)`.
        expected: String,
        /// The shape given.
        got: String,
    },
    /// The pixels of a row are not next to each other, or rows are not in order.
    #[error(
        "{camera}: the frame's {what} (strides {strides:?} bytes): pass \
         numpy.ascontiguousarray(frame)"
    )]
    Strides {
        /// `camera 0 (cam0)`.
        camera: String,
        /// What is wrong.
        what: &'static str,
        /// The strides given.
        strides: Vec<isize>,
    },
}

fn shape_text(shape: &[usize]) -> String {
    match shape {
        [n] => format!("({n},)"),
        _ => format!(
            "({})",
            shape
                .iter()
                .map(|n| n.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        ),
    }
}

/// The frame that `array` holds for a camera calibrated for `format` frames of
/// `width` x `height` px: `(height, width)` for mono and Bayer formats, `(height, width, 3)`
/// for `rgb8`; `uint8` for 8-bit formats, `uint16` (native byte order) for 16-bit ones. Rows
/// may be padded or every other row of a bigger array (any row stride at least a row's
/// bytes); the pixels of a row must be next to each other.
pub fn frame_layout(
    array: &ArrayLayout<'_>,
    format: PixelFormat,
    width: usize,
    height: usize,
    camera: &str,
) -> Result<FrameLayout, LayoutError> {
    let bpp = format.bytes_per_pixel();
    let (expected_dtype, channels) = match format {
        PixelFormat::Rgb8 => ("uint8", 3),
        f if f.is_16bit() => ("uint16", 1),
        _ => ("uint8", 1),
    };
    if array.dtype != expected_dtype || array.itemsize * channels != bpp {
        return Err(LayoutError::Dtype {
            camera: camera.into(),
            format,
            expected: expected_dtype,
            got: array.dtype.into(),
        });
    }
    let expected: Vec<usize> = if channels == 3 {
        vec![height, width, 3]
    } else {
        vec![height, width]
    };
    if array.shape != expected.as_slice() || array.strides.len() != array.shape.len() {
        return Err(LayoutError::Shape {
            camera: camera.into(),
            format,
            expected: shape_text(&expected),
            got: shape_text(array.shape),
        });
    }
    let strides_err = |what| LayoutError::Strides {
        camera: camera.into(),
        what,
        strides: array.strides.to_vec(),
    };
    let item = array.itemsize as isize;
    let packed = if channels == 3 {
        array.strides[1] == 3 * item && array.strides[2] == item
    } else {
        array.strides[1] == item
    };
    if !packed {
        return Err(strides_err("pixels of a row are not next to each other"));
    }
    let row_bytes = width * bpp;
    let stride_bytes = usize::try_from(array.strides[0])
        .ok()
        .filter(|s| *s >= row_bytes)
        .ok_or_else(|| strides_err("rows do not follow each other top to bottom"))?;
    Ok(FrameLayout {
        width,
        height,
        stride_bytes,
        len_bytes: stride_bytes * (height - 1) + row_bytes,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn layout(
        dtype: &str,
        itemsize: usize,
        shape: &[usize],
        strides: &[isize],
        format: PixelFormat,
    ) -> Result<FrameLayout, LayoutError> {
        let a = ArrayLayout {
            dtype,
            itemsize,
            shape,
            strides,
        };
        frame_layout(&a, format, 8, 4, "camera 0 (cam0)")
    }

    #[test]
    fn packed_and_padded_rows_are_borrowed() {
        let f = layout("uint8", 1, &[4, 8], &[8, 1], PixelFormat::BayerRggb8);
        assert_eq!(
            f,
            Ok(FrameLayout {
                width: 8,
                height: 4,
                stride_bytes: 8,
                len_bytes: 32
            })
        );
        // A crop of a wider frame, or every other row of a taller one.
        let f = layout("uint8", 1, &[4, 8], &[24, 1], PixelFormat::Mono8);
        assert_eq!(f.map(|f| (f.stride_bytes, f.len_bytes)), Ok((24, 80)));
        let f = layout("uint16", 2, &[4, 8], &[32, 2], PixelFormat::Mono16);
        assert_eq!(f.map(|f| (f.stride_bytes, f.len_bytes)), Ok((32, 112)));
        let f = layout("uint8", 1, &[4, 8, 3], &[24, 3, 1], PixelFormat::Rgb8);
        assert_eq!(f.map(|f| f.len_bytes), Ok(96));
    }

    #[test]
    fn layouts_that_do_not_fit_are_refused_with_what_to_pass() {
        let e = layout("uint16", 2, &[4, 8], &[16, 2], PixelFormat::BayerRggb8).unwrap_err();
        assert_eq!(
            e.to_string(),
            "camera 0 (cam0) is calibrated for bayer_rggb8 frames: give a uint8 array, got uint16"
        );
        let e = layout("float32", 4, &[4, 8], &[32, 4], PixelFormat::Mono16).unwrap_err();
        assert!(matches!(e, LayoutError::Dtype { .. }), "{e}");
        let e = layout("uint8", 1, &[8, 4], &[4, 1], PixelFormat::Mono8).unwrap_err();
        assert!(
            e.to_string().contains("of shape (4, 8): got shape (8, 4)"),
            "{e}"
        );
        let e = layout("uint8", 1, &[4, 8], &[8, 1], PixelFormat::Rgb8).unwrap_err();
        assert!(e.to_string().contains("(4, 8, 3)"), "{e}");
        // A transposed view (columns apart), a reversed one (negative row stride).
        let e = layout("uint8", 1, &[4, 8], &[1, 4], PixelFormat::Mono8).unwrap_err();
        assert!(
            e.to_string().contains("pixels of a row are not next"),
            "{e}"
        );
        assert!(e.to_string().contains("ascontiguousarray"), "{e}");
        let e = layout("uint8", 1, &[4, 8], &[-8, 1], PixelFormat::Mono8).unwrap_err();
        assert!(e.to_string().contains("top to bottom"), "{e}");
        // Rows overlapping (a stride shorter than a row).
        let e = layout("uint8", 1, &[4, 8], &[4, 1], PixelFormat::Mono8).unwrap_err();
        assert!(matches!(e, LayoutError::Strides { .. }), "{e}");
    }
}
