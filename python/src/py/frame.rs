//! Frames from numpy, borrowed without a copy (strides honoured), and `read_frame`.

use super::errors::RodtrackError;
use crate::layout::{frame_layout, ArrayLayout, FrameLayout, LayoutError};
use numpy::{
    dtype, PyArray2, PyArray3, PyArrayDescrMethods, PyArrayMethods, PyReadonlyArray2,
    PyReadonlyArray3, PyUntypedArray, PyUntypedArrayMethods,
};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use rodtrack_core::{FrameView, PixelFormat};
use std::path::PathBuf;

/// The read-only borrow that keeps the array alive and unwritable from Rust.
enum Guard<'py> {
    U8(PyReadonlyArray2<'py, u8>),
    U16(PyReadonlyArray2<'py, u16>),
    Rgb(PyReadonlyArray3<'py, u8>),
}

/// A numpy array borrowed as a camera's frame.
pub struct BorrowedFrame<'py> {
    guard: Guard<'py>,
    layout: FrameLayout,
    format: PixelFormat,
}

fn layout_err(e: LayoutError) -> PyErr {
    match e {
        LayoutError::Dtype { .. } => PyTypeError::new_err(e.to_string()),
        _ => PyValueError::new_err(e.to_string()),
    }
}

impl<'py> BorrowedFrame<'py> {
    /// Borrows `obj` as a frame of a camera calibrated for `format` frames of `width` x
    /// `height` px ([`frame_layout`]): TypeError for another element type, ValueError for
    /// another shape or strides that cannot be a frame.
    pub fn borrow(
        obj: &Bound<'py, PyAny>,
        format: PixelFormat,
        width: usize,
        height: usize,
        camera: &str,
    ) -> PyResult<BorrowedFrame<'py>> {
        let py = obj.py();
        let array = obj.cast::<PyUntypedArray>().map_err(|_| {
            PyTypeError::new_err(format!(
                "{camera}: the frame must be a numpy array, got {}",
                obj.get_type()
                    .name()
                    .map(|n| n.to_string())
                    .unwrap_or_else(|_| "?".into())
            ))
        })?;
        let descr = array.dtype();
        let name = if descr.is_equiv_to(&dtype::<u8>(py)) {
            "uint8".to_string()
        } else if descr.is_equiv_to(&dtype::<u16>(py)) {
            "uint16".to_string()
        } else {
            // Other types, and uint16 in the other byte order.
            descr
                .str()
                .map(|s| s.to_string())
                .unwrap_or_else(|_| "?".into())
        };
        let layout = frame_layout(
            &ArrayLayout {
                dtype: &name,
                itemsize: descr.itemsize(),
                shape: array.shape(),
                strides: array.strides(),
            },
            format,
            width,
            height,
            camera,
        )
        .map_err(layout_err)?;
        let borrow_err = |e: numpy::BorrowError| {
            PyValueError::new_err(format!("{camera}: the frame cannot be borrowed: {e}"))
        };
        let guard = match (format, name.as_str()) {
            (PixelFormat::Rgb8, _) => Guard::Rgb(
                obj.cast::<PyArray3<u8>>()?
                    .try_readonly()
                    .map_err(borrow_err)?,
            ),
            (_, "uint16") => Guard::U16(
                obj.cast::<PyArray2<u16>>()?
                    .try_readonly()
                    .map_err(borrow_err)?,
            ),
            _ => Guard::U8(
                obj.cast::<PyArray2<u8>>()?
                    .try_readonly()
                    .map_err(borrow_err)?,
            ),
        };
        Ok(BorrowedFrame {
            guard,
            layout,
            format,
        })
    }

    /// The frame's bytes, from its first pixel to the end of its last row's pixels.
    #[allow(unsafe_code)]
    fn bytes(&self) -> &[u8] {
        let ptr = match &self.guard {
            Guard::U8(a) => a.data() as *const u8,
            Guard::U16(a) => a.data() as *const u8,
            Guard::Rgb(a) => a.data() as *const u8,
        };
        // SAFETY: `frame_layout` checked that the array's rows follow each other top to bottom
        // (a positive row stride of at least a row's bytes) with the pixels of a row next to
        // each other, so the `len_bytes` bytes from the first element all lie within the
        // array's memory; `self.guard` keeps the array alive (a reference) and read-only to
        // Rust (numpy's borrow flag) for the slice's lifetime. Python code writing to the array
        // from another thread meanwhile would race, as with any buffer shared with C; the
        // documentation says not to.
        unsafe { std::slice::from_raw_parts(ptr, self.layout.len_bytes) }
    }

    /// The frame as the core's view.
    pub fn view(&self) -> PyResult<FrameView<'_>> {
        FrameView::new(
            self.bytes(),
            self.layout.width,
            self.layout.height,
            self.layout.stride_bytes,
            self.format,
        )
        .map_err(|e| PyValueError::new_err(e.to_string()))
    }
}

/// Reads an image file (PNG, PGM, TIFF) as a camera frame: a numpy array of shape
/// ``(height, width)`` (``uint8``, or ``uint16`` for 16-bit formats) or ``(height, width, 3)``
/// for ``rgb8``, decoded as ``pixel_format`` says (default: from the file).
#[pyfunction]
#[pyo3(signature = (path, pixel_format = None))]
pub fn read_frame<'py>(
    py: Python<'py>,
    path: PathBuf,
    pixel_format: Option<&str>,
) -> PyResult<Bound<'py, PyAny>> {
    let format = pixel_format
        .map(|name| {
            PixelFormat::from_name(name)
                .ok_or_else(|| PyValueError::new_err(format!("unknown pixel format {name:?}")))
        })
        .transpose()?;
    let mut buf = rodtrack_io::FrameBuffer::new();
    py.detach(|| rodtrack_io::source::decode_image_file(&path, format, &mut buf))
        .map_err(|e| RodtrackError::new_err(e.to_string()))?;
    let m = buf.meta;
    let row_bytes = m.width * m.format.bytes_per_pixel();
    let mut packed = Vec::with_capacity(row_bytes * m.height);
    for y in 0..m.height {
        let row = buf.row(y).ok_or_else(|| {
            RodtrackError::new_err(format!("{}: row {y} missing", path.display()))
        })?;
        packed.extend_from_slice(&row[..row_bytes.min(row.len())]);
    }
    let flat = numpy::PyArray1::from_vec(py, packed);
    let array = match m.format {
        PixelFormat::Rgb8 => flat.reshape([m.height, m.width, 3])?.into_any(),
        f if f.is_16bit() => {
            let words: Vec<u16> = flat
                .readonly()
                .as_slice()?
                .chunks_exact(2)
                .map(|b| u16::from_le_bytes([b[0], b[1]]))
                .collect();
            numpy::PyArray1::from_vec(py, words)
                .reshape([m.height, m.width])?
                .into_any()
        }
        _ => flat.reshape([m.height, m.width])?.into_any(),
    };
    Ok(array)
}
