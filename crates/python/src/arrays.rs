//! numpy arrays in and out: records read in place, films (a reference,
//! OIDN's albedo and normal) checked against the dump's, images as the
//! command's EXRs hold them.

use numpy::{
    PyArray1, PyArray2, PyArrayDescrMethods, PyArrayDyn, PyArrayMethods, PyUntypedArray,
    PyUntypedArrayMethods,
};
use pyo3::prelude::*;

use pathdensity_core::imagespace::aux::Aux;
use pathdensity_format::dump::{Header, Record};
use pathdensity_format::image::{Image, stored};

use crate::errors::value_error;

/// A shape as Python prints it: `(8, 7, 3)`, `(5,)`.
pub(crate) fn shape_str(shape: &[usize]) -> String {
    let items: Vec<String> = shape.iter().map(|n| n.to_string()).collect();
    match items.as_slice() {
        [one] => format!("({one},)"),
        _ => format!("({})", items.join(", ")),
    }
}

/// The records of `array` without a copy: a C-contiguous, aligned
/// `(N, 6)` float32 array (x, y, t, r, g, b, docs/format.md).
pub(crate) fn records_of<'a>(
    array: &'a Bound<'_, PyAny>,
) -> PyResult<numpy::PyReadonlyArray2<'a, f32>> {
    let py = array.py();
    let Ok(untyped) = array.cast::<PyUntypedArray>() else {
        let kind = array.get_type().name()?;
        return Err(value_error(format!(
            "records must be a numpy array of shape (N, 6) and dtype float32, got a {kind}"
        )));
    };
    let dtype = untyped.dtype();
    if !dtype.is_equiv_to(&numpy::dtype::<f32>(py)) {
        return Err(value_error(format!(
            "records must have dtype float32 (x, y, t, r, g, b as 24-byte records), got {} (convert with records.astype(numpy.float32))",
            dtype.str()?
        )));
    }
    let shape = untyped.shape();
    if shape.len() != 2 || shape[1] != 6 {
        return Err(value_error(format!(
            "records must have shape (N, 6) (x, y, t, r, g, b), got {}",
            shape_str(shape)
        )));
    }
    if !untyped.is_c_contiguous() {
        return Err(value_error(
            "records must be C-contiguous (row after row, as a dump holds them); the filter reads them in place and copies nothing: pass numpy.ascontiguousarray(records)",
        ));
    }
    let typed = untyped.cast::<PyArray2<f32>>()?;
    let readonly = typed
        .try_readonly()
        .map_err(|e| value_error(e.to_string()))?;
    // Checked here once, so that `as_records` cannot fail.
    bytemuck::try_cast_slice::<f32, Record>(readonly.as_slice()?).map_err(|_| {
        value_error("records must be aligned to 4 bytes (numpy.ascontiguousarray(records))")
    })?;
    Ok(readonly)
}

pub(crate) fn as_records<'a>(array: &'a numpy::PyReadonlyArray2<'_, f32>) -> &'a [Record] {
    let floats = array.as_slice().expect("checked C-contiguous");
    bytemuck::cast_slice(floats)
}

/// A reference image as the pipeline takes it ([`film_of`]), finite.
pub(crate) fn reference_of(r: &Bound<'_, PyAny>, h: &Header) -> PyResult<Image> {
    let img = film_of("reference", r, h)?;
    if img.data.iter().flatten().any(|v| !v.is_finite()) {
        return Err(value_error("reference holds non-finite values"));
    }
    Ok(img)
}

/// `name`'s float32 or float64 array of the film's shape, `(H, W, 3)` for
/// a still or `(frames, H, W, 3)` for any film, as an image.
pub(crate) fn film_of(name: &str, r: &Bound<'_, PyAny>, h: &Header) -> PyResult<Image> {
    let (w, ht, f) = (h.width as usize, h.height as usize, h.frames as usize);
    let py = r.py();
    let np = py.import("numpy")?;
    // float32 and float64 as float64 (the CLI reads an EXR's f32 into f64);
    // a copy, as the reference is small beside the records.
    let array = np.call_method1("asarray", (r, "float64"))?;
    let array = array
        .cast::<PyArrayDyn<f64>>()
        .map_err(|_| value_error(format!("{name} must be a float array")))?;
    let shape = array.shape().to_vec();
    let ok = match shape.as_slice() {
        [hh, ww, 3] => f == 1 && (*hh, *ww) == (ht, w),
        [ff, hh, ww, 3] => (*ff, *hh, *ww) == (f, ht, w),
        _ => false,
    };
    if !ok {
        return Err(value_error(format!(
            "{name} has shape {}, the film is {f} frames of {w} × {ht} (expected ({f}, {ht}, {w}, 3){})",
            shape_str(&shape),
            if f == 1 {
                format!(" or ({ht}, {w}, 3)")
            } else {
                String::new()
            }
        )));
    }
    let ro = array.readonly();
    let view = ro.as_array();
    let mut img = Image::new(w, ht, f);
    for (p, px) in view
        .as_standard_layout()
        .as_slice()
        .expect("standard layout")
        .chunks_exact(3)
        .zip(img.data.iter_mut())
    {
        *px = [p[0], p[1], p[2]];
    }
    Ok(img)
}

/// The renderer's albedo and normal (OIDN's auxiliary images, statmc's
/// guide) from `albedo=` and `normal=`, checked as the command checks
/// `--albedo` and `--normal`.
pub(crate) fn aux_of(
    albedo: Option<&Bound<'_, PyAny>>,
    normal: Option<&Bound<'_, PyAny>>,
    h: &Header,
) -> PyResult<Option<Aux>> {
    let Some(albedo) = albedo else {
        if normal.is_some() {
            return Err(value_error(
                "normal needs albedo (a normal is taken only with an albedo)",
            ));
        }
        return Ok(None);
    };
    let albedo = film_of("albedo", albedo, h)?;
    let normal = normal.map(|n| film_of("normal", n, h)).transpose()?;
    Ok(Some(Aux::new(&albedo, normal.as_ref())))
}

/// An image as the `filter` command writes it to EXR (rounded to f32,
/// clamped to the finite range), shape `(frames, H, W, 3)`.
pub(crate) fn image_array<'py>(py: Python<'py>, img: &Image) -> PyResult<Bound<'py, PyAny>> {
    let values: Vec<f32> = img.data.iter().flatten().map(|&v| stored(v)).collect();
    Ok(PyArray1::from_vec(py, values)
        .reshape([img.frames, img.height, img.width, 3])?
        .into_any())
}
