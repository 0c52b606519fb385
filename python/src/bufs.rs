//! The step buffers of a `VecCore`: numpy arrays it owns, bound for one call and seen
//! as slices (each checked for its length) while the GIL is released.

use fulcrum_world::ObsSpec;
use numpy::{PyArray1, PyArray2, PyArray3, PyArrayMethods};
use pyo3::prelude::*;

use crate::errors::value_error;

/// Mutable views of the step buffers, for one step with the GIL released.
pub(crate) struct Views<'a> {
    pub(crate) glyphs: &'a mut [u8],
    pub(crate) flags: &'a mut [u8],
    pub(crate) mask: &'a mut [i8],
    pub(crate) reward: &'a mut [f32],
    pub(crate) terminated: &'a mut [bool],
    pub(crate) truncated: &'a mut [bool],
    pub(crate) states: &'a mut [u8],
    pub(crate) layout: &'a mut [u64],
}

/// The step buffers, bound for one call.
pub(crate) struct Bufs<'py> {
    pub(crate) glyphs: Bound<'py, PyArray3<u8>>,
    pub(crate) flags: Bound<'py, PyArray2<u8>>,
    pub(crate) mask: Bound<'py, PyArray2<i8>>,
    pub(crate) reward: Bound<'py, PyArray1<f32>>,
    pub(crate) terminated: Bound<'py, PyArray1<bool>>,
    pub(crate) truncated: Bound<'py, PyArray1<bool>>,
    pub(crate) states: Bound<'py, PyArray2<u8>>,
    pub(crate) layout: Bound<'py, PyArray1<u64>>,
}

/// `got` if it is a slice of `len` elements, else the error that says the array changed.
pub(crate) fn checked<'b, T>(
    what: &str,
    got: Result<&'b mut [T], numpy::AsSliceError>,
    len: usize,
) -> PyResult<&'b mut [T]> {
    match got {
        Ok(v) if v.len() == len => Ok(v),
        _ => Err(value_error(format!(
            "the environment's {what} array was changed (resized or made non-contiguous): it must stay as the environment made it"
        ))),
    }
}

impl Bufs<'_> {
    /// The buffers as slices, each checked for its length (a caller who resized an array
    /// gets an error, not a write out of bounds).
    ///
    /// # Safety
    /// No other reference to these arrays' data may be used while the views live: the
    /// arrays are the environment's, handed to Python only to be read between calls.
    pub(crate) unsafe fn views(
        &self,
        n: usize,
        spec: &ObsSpec,
        actions: usize,
    ) -> PyResult<Views<'_>> {
        unsafe {
            Ok(Views {
                glyphs: checked("glyphs", self.glyphs.as_slice_mut(), n * spec.cells())?,
                flags: checked("flags", self.flags.as_slice_mut(), n * spec.flags)?,
                mask: checked("action_mask", self.mask.as_slice_mut(), n * actions)?,
                reward: checked("reward", self.reward.as_slice_mut(), n)?,
                terminated: checked("terminated", self.terminated.as_slice_mut(), n)?,
                truncated: checked("truncated", self.truncated.as_slice_mut(), n)?,
                states: checked(
                    "states",
                    self.states.as_slice_mut(),
                    n * fulcrum_contracts::msg::STATE_BYTES,
                )?,
                layout: checked("layout", self.layout.as_slice_mut(), n)?,
            })
        }
    }
}
