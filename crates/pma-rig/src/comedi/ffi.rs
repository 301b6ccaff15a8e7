//! The real libcomedi (feature `comedi`): hand-written declarations of the few functions
//! this driver uses (signatures from comedilib 0.11's `comedilib.h`; there is no `-sys`
//! crate), and [`FfiLib`], the safe [`ComediLib`] over them. `build.rs` links the library
//! through pkg-config.

use std::ffi::{c_char, c_double, c_int, c_uint, CStr, CString};
use std::ptr::NonNull;

use super::{
    ComediError, ComediLib, ConversionDirection, Polynomial, Range, RangeUnit, SubdeviceKind,
};

/// `comedi_t`: opaque, owned by the library between `comedi_open` and `comedi_close`.
#[repr(C)]
struct ComediT {
    _opaque: [u8; 0],
    // Neither Send, Sync nor Unpin by itself: the library owns it.
    _marker: std::marker::PhantomData<(*mut u8, std::marker::PhantomPinned)>,
}

/// `comedi_range`.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
struct ComediRange {
    min: c_double,
    max: c_double,
    unit: c_uint,
}

/// `comedi_polynomial_t`.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default)]
struct ComediPolynomial {
    coefficients: [c_double; Polynomial::MAX_COEFFICIENTS],
    expansion_origin: c_double,
    order: c_uint,
}

/// `lsampl_t`.
type Lsampl = c_uint;

/// `COMEDI_OUTPUT` (`enum comedi_io_direction`).
const COMEDI_OUTPUT: c_uint = 1;
/// `COMEDI_TO_PHYSICAL` (`enum comedi_conversion_direction`).
const COMEDI_TO_PHYSICAL: c_uint = 0;
/// `COMEDI_FROM_PHYSICAL`.
const COMEDI_FROM_PHYSICAL: c_uint = 1;

unsafe extern "C" {
    fn comedi_open(filename: *const c_char) -> *mut ComediT;
    fn comedi_close(it: *mut ComediT) -> c_int;
    fn comedi_errno() -> c_int;
    fn comedi_strerror(errnum: c_int) -> *const c_char;
    fn comedi_get_board_name(it: *mut ComediT) -> *const c_char;
    fn comedi_get_n_subdevices(it: *mut ComediT) -> c_int;
    fn comedi_get_subdevice_type(it: *mut ComediT, subdevice: c_uint) -> c_int;
    fn comedi_get_n_channels(it: *mut ComediT, subdevice: c_uint) -> c_int;
    fn comedi_get_n_ranges(it: *mut ComediT, subdevice: c_uint, chan: c_uint) -> c_int;
    fn comedi_get_range(
        it: *mut ComediT,
        subdevice: c_uint,
        chan: c_uint,
        range: c_uint,
    ) -> *mut ComediRange;
    fn comedi_get_maxdata(it: *mut ComediT, subdevice: c_uint, chan: c_uint) -> Lsampl;
    // The C enum parameter is passed as `unsigned`: the enum has only the values 0 and 1,
    // and C enums are `int`-sized on the Linux ABIs, so both are passed identically.
    fn comedi_get_hardcal_converter(
        dev: *mut ComediT,
        subdevice: c_uint,
        channel: c_uint,
        range: c_uint,
        direction: c_uint,
        polynomial: *mut ComediPolynomial,
    ) -> c_int;
    fn comedi_data_read(
        it: *mut ComediT,
        subd: c_uint,
        chan: c_uint,
        range: c_uint,
        aref: c_uint,
        data: *mut Lsampl,
    ) -> c_int;
    fn comedi_data_write(
        it: *mut ComediT,
        subd: c_uint,
        chan: c_uint,
        range: c_uint,
        aref: c_uint,
        data: Lsampl,
    ) -> c_int;
    fn comedi_dio_config(it: *mut ComediT, subd: c_uint, chan: c_uint, dir: c_uint) -> c_int;
    fn comedi_dio_write(it: *mut ComediT, subd: c_uint, chan: c_uint, bit: c_uint) -> c_int;
}

/// The last error of the calling thread, read right after the failed call (comedilib keeps
/// its errno in thread-local storage and never clears it, so it is only meaningful then).
fn last_error(call: &'static str) -> ComediError {
    // SAFETY: `comedi_errno` only reads a thread-local integer.
    let errno = unsafe { comedi_errno() };
    // SAFETY: `comedi_strerror` accepts any integer and returns a NUL-terminated string
    // (comedilib's table or libc's `strerror`), or NULL, checked below.
    let text = unsafe { comedi_strerror(errno) };
    let message = if text.is_null() {
        format!("unknown error {errno}")
    } else {
        // SAFETY: non-null and NUL-terminated; copied before any other libc call on this
        // thread could overwrite `strerror`'s buffer.
        unsafe { CStr::from_ptr(text) }
            .to_string_lossy()
            .into_owned()
    };
    ComediError {
        call,
        errno,
        message,
    }
}

/// An `int` result that is -1 on error, as a count or index.
fn non_negative(value: c_int, call: &'static str) -> Result<u32, ComediError> {
    u32::try_from(value).map_err(|_| last_error(call))
}

/// A `0 on success, -1 on error` result.
fn status(value: c_int, call: &'static str) -> Result<(), ComediError> {
    if value < 0 {
        Err(last_error(call))
    } else {
        Ok(())
    }
}

/// One opened Comedi device (`comedi_t *`); dropping it closes the device.
#[derive(Debug)]
pub struct FfiLib {
    dev: NonNull<ComediT>,
    path: String,
}

// SAFETY: the `comedi_t` is owned by this value alone (never shared or aliased) and
// comedilib has no thread affinity: a device may be used from whichever single thread
// owns it at a time. Its errno is thread-local and read on the thread that made the call
// (`last_error` runs inside the same method). `FfiLib` is not `Sync`.
unsafe impl Send for FfiLib {}

impl FfiLib {
    /// The device pointer for a library call.
    fn ptr(&self) -> *mut ComediT {
        self.dev.as_ptr()
    }

    /// The device path it was opened with.
    pub fn path(&self) -> &str {
        &self.path
    }
}

impl Drop for FfiLib {
    fn drop(&mut self) {
        // SAFETY: `dev` came from `comedi_open` and is closed exactly once, here. A failure
        // to close cannot be reported from `drop` and leaves nothing to clean up.
        unsafe {
            comedi_close(self.ptr());
        }
    }
}

impl ComediLib for FfiLib {
    fn open(path: &str) -> Result<Self, ComediError> {
        let c_path = CString::new(path).map_err(|_| ComediError {
            call: "comedi_open",
            errno: libc::EINVAL,
            message: String::from("the device path contains a NUL byte"),
        })?;
        // SAFETY: `c_path` is a valid NUL-terminated string that outlives the call;
        // comedilib does not keep the pointer.
        let dev = unsafe { comedi_open(c_path.as_ptr()) };
        let dev = NonNull::new(dev).ok_or_else(|| last_error("comedi_open"))?;
        Ok(Self {
            dev,
            path: path.to_owned(),
        })
    }

    fn reopen(&self) -> Result<Self, ComediError> {
        Self::open(&self.path)
    }

    fn board_name(&self) -> Result<String, ComediError> {
        // SAFETY: `dev` is open; the result is NULL or a string inside the `comedi_t`.
        let name = unsafe { comedi_get_board_name(self.ptr()) };
        if name.is_null() {
            return Err(last_error("comedi_get_board_name"));
        }
        // SAFETY: non-null, NUL-terminated, and valid while `dev` is open (it is copied now).
        Ok(unsafe { CStr::from_ptr(name) }
            .to_string_lossy()
            .into_owned())
    }

    fn n_subdevices(&self) -> Result<u32, ComediError> {
        // SAFETY: `dev` is open.
        let count = unsafe { comedi_get_n_subdevices(self.ptr()) };
        non_negative(count, "comedi_get_n_subdevices")
    }

    fn subdevice_kind(&self, subdevice: u32) -> Result<SubdeviceKind, ComediError> {
        // SAFETY: `dev` is open; comedilib checks the index.
        let kind = unsafe { comedi_get_subdevice_type(self.ptr(), subdevice) };
        if kind < 0 {
            return Err(last_error("comedi_get_subdevice_type"));
        }
        Ok(SubdeviceKind::from_comedi(kind))
    }

    fn n_channels(&self, subdevice: u32) -> Result<u32, ComediError> {
        // SAFETY: `dev` is open; comedilib checks the index.
        let count = unsafe { comedi_get_n_channels(self.ptr(), subdevice) };
        non_negative(count, "comedi_get_n_channels")
    }

    fn n_ranges(&self, subdevice: u32, channel: u32) -> Result<u32, ComediError> {
        // SAFETY: `dev` is open; comedilib checks the indices.
        let count = unsafe { comedi_get_n_ranges(self.ptr(), subdevice, channel) };
        non_negative(count, "comedi_get_n_ranges")
    }

    fn range(&self, subdevice: u32, channel: u32, range: u32) -> Result<Range, ComediError> {
        // SAFETY: `dev` is open; comedilib checks the indices and returns NULL or a pointer
        // into the `comedi_t`'s tables.
        let pointer = unsafe { comedi_get_range(self.ptr(), subdevice, channel, range) };
        // SAFETY: when non-null, it points to a `comedi_range` valid while `dev` is open; it
        // is copied at once.
        let raw = unsafe { pointer.as_ref() }
            .copied()
            .ok_or_else(|| last_error("comedi_get_range"))?;
        Ok(Range {
            min: raw.min,
            max: raw.max,
            unit: RangeUnit::from_comedi(raw.unit),
        })
    }

    fn maxdata(&self, subdevice: u32, channel: u32) -> Result<u32, ComediError> {
        // SAFETY: `dev` is open; comedilib checks the indices (0 on error).
        let maxdata = unsafe { comedi_get_maxdata(self.ptr(), subdevice, channel) };
        if maxdata == 0 {
            return Err(last_error("comedi_get_maxdata"));
        }
        Ok(maxdata)
    }

    fn hardcal(
        &self,
        subdevice: u32,
        channel: u32,
        range: u32,
        direction: ConversionDirection,
    ) -> Option<Polynomial> {
        let direction = match direction {
            ConversionDirection::ToPhysical => COMEDI_TO_PHYSICAL,
            ConversionDirection::FromPhysical => COMEDI_FROM_PHYSICAL,
        };
        let mut raw = ComediPolynomial::default();
        // SAFETY: `dev` is open and `raw` is a writable `comedi_polynomial_t` for the call.
        let result = unsafe {
            comedi_get_hardcal_converter(self.ptr(), subdevice, channel, range, direction, &mut raw)
        };
        // comedilib asserts `order < 4` when applying a polynomial: refuse others here.
        if result < 0 || raw.order as usize >= Polynomial::MAX_COEFFICIENTS {
            return None;
        }
        Some(Polynomial {
            coefficients: raw.coefficients,
            expansion_origin: raw.expansion_origin,
            order: raw.order,
        })
    }

    fn data_read(
        &mut self,
        subdevice: u32,
        channel: u32,
        range: u32,
        aref: u32,
    ) -> Result<u32, ComediError> {
        let mut code: Lsampl = 0;
        // SAFETY: `dev` is open and `code` is a writable `lsampl_t` for the call.
        let result =
            unsafe { comedi_data_read(self.ptr(), subdevice, channel, range, aref, &mut code) };
        status(result, "comedi_data_read")?;
        Ok(code)
    }

    fn data_write(
        &mut self,
        subdevice: u32,
        channel: u32,
        range: u32,
        aref: u32,
        code: u32,
    ) -> Result<(), ComediError> {
        // SAFETY: `dev` is open; the arguments are plain integers checked by the driver.
        let result =
            unsafe { comedi_data_write(self.ptr(), subdevice, channel, range, aref, code) };
        status(result, "comedi_data_write")
    }

    fn dio_config_output(&mut self, subdevice: u32, channel: u32) -> Result<(), ComediError> {
        // SAFETY: `dev` is open; the arguments are plain integers checked by the driver.
        let result = unsafe { comedi_dio_config(self.ptr(), subdevice, channel, COMEDI_OUTPUT) };
        status(result, "comedi_dio_config")
    }

    fn dio_write(&mut self, subdevice: u32, channel: u32, high: bool) -> Result<(), ComediError> {
        // SAFETY: `dev` is open; the arguments are plain integers checked by the driver.
        let result =
            unsafe { comedi_dio_write(self.ptr(), subdevice, channel, c_uint::from(high)) };
        status(result, "comedi_dio_write")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Links against the installed libcomedi and maps a missing device to an error that
    /// names it and says what to do (no board is needed: the node does not exist).
    #[test]
    fn opening_a_missing_device_says_what_to_do() {
        let result = super::super::ComediDaq::<FfiLib>::open("/dev/comedi-pma-exo-missing");
        match result {
            Err(crate::DaqError::Open { device, message }) => {
                assert_eq!(device, "/dev/comedi-pma-exo-missing");
                assert!(message.contains("No such file or directory"), "{message}");
                assert!(message.contains("kernel driver"), "{message}");
            }
            other => panic!("expected an open error, got {other:?}"),
        }
    }

    #[test]
    fn a_nul_in_the_path_is_an_error_not_a_panic() {
        let error = FfiLib::open("/dev/comedi\0").err();
        assert_eq!(error.map(|e| e.errno), Some(libc::EINVAL));
    }
}
