//! The Python module `pathdensity`: the filter on numpy arrays.
//!
//! A thin layer: it converts arrays (`arrays`), keyword arguments
//! (`keywords`) and errors (`errors`), and calls
//! `pathdensity_core::pipeline::run` and the format crate's dump reader
//! and writer. No filter logic lives here, so the module's
//! decisions and images are the `filter` command's, byte for byte
//! (`tests/test_pathdensity.py` holds it to that).

use std::path::PathBuf;

use numpy::ndarray::ArrayView2;
use numpy::{PyArray1, PyArray2, PyUntypedArray};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use pathdensity_core::density::ExactSigma;
use pathdensity_core::pipeline::{self, RunOptions};
use pathdensity_core::progress::Silent;
use pathdensity_format::dump::{DumpReader, DumpWriter, Header, Order};

mod arrays;
mod errors;
mod keywords;

use arrays::{as_records, aux_of, image_array, records_of, reference_of};
use errors::{os_error, pipeline_error, value_error};
use keywords::config_of;

/// `order` by name: `unspecified`, `pixel` or `pass` (also `pixel-major`,
/// `pass-major`, as the dump's header spells them).
fn order_of(name: &str) -> PyResult<Order> {
    match name {
        "unspecified" => Ok(Order::Unspecified),
        "pixel" | "pixel-major" => Ok(Order::PixelMajor),
        "pass" | "pass-major" => Ok(Order::PassMajor),
        _ => Err(value_error(format!(
            "unknown order {name:?} (unspecified, pixel, pass)"
        ))),
    }
}

fn order_name(order: Order) -> &'static str {
    match order {
        Order::Unspecified => "unspecified",
        Order::PixelMajor => "pixel",
        Order::PassMajor => "pass",
    }
}

/// The header of `count` records, checked as a dump reader checks one.
fn header_of(
    width: u32,
    height: u32,
    frames: u32,
    spp: u32,
    order: &str,
    count: usize,
) -> PyResult<Header> {
    let mut h = Header::still(width, height, spp, order_of(order)?);
    h.frames = frames;
    h.sample_count = count as u64;
    h.validate().map_err(value_error)?;
    Ok(h)
}

/// `json.loads` of `value`'s serde form: the dicts of report.json.
fn json_object<'py>(py: Python<'py>, value: &impl serde::Serialize) -> PyResult<Bound<'py, PyAny>> {
    let text = serde_json::to_string(value).expect("serialisable");
    py.import("json")?.call_method1("loads", (text,))
}

/// What `filter` returns.
#[pyclass(frozen, module = "pathdensity")]
struct FilterResult {
    /// Image name (as report.json names them: `filtered`, `median`,
    /// `filtered+oidn`, …) → float32 array `(frames, H, W, 3)`, the
    /// values the command's EXRs hold.
    #[pyo3(get)]
    images: Py<PyDict>,
    /// One byte per record, as `filter --decisions` writes them: 0
    /// invalid, 1 accepted while streaming, 2 accepted in the final pass,
    /// 3 rejected.
    #[pyo3(get)]
    decisions: Py<PyAny>,
    /// report.json's "counts".
    #[pyo3(get)]
    counts: Py<PyAny>,
    /// report.json's "metrics" (empty without a reference).
    #[pyo3(get)]
    metrics: Py<PyAny>,
    /// The recommended image's name, or None.
    #[pyo3(get)]
    recommended: Option<String>,
    /// report.json's "denoiser".
    #[pyo3(get)]
    denoiser: Option<String>,
    /// `mean − filtered` (the command's rejected.exr).
    #[pyo3(get)]
    rejected: Py<PyAny>,
    /// Per pixel the mean exact σ (the command's sigma.exr), with
    /// `sigma_map=True`; else None.
    #[pyo3(get)]
    sigma: Option<Py<PyAny>>,
    /// report.json's "config": the configuration as run.
    #[pyo3(get)]
    config: Py<PyAny>,
    /// The white luminance Y_w used.
    #[pyo3(get)]
    white: f64,
    #[pyo3(get)]
    threads: usize,
    #[pyo3(get)]
    fallback_pixels: u64,
    #[pyo3(get)]
    empty_pixels: u64,
    /// report.json's "warnings".
    #[pyo3(get)]
    warnings: Vec<String>,
}

#[pymethods]
impl FilterResult {
    fn __repr__(&self, py: Python<'_>) -> PyResult<String> {
        let names: Vec<String> = self.images.bind(py).keys().extract()?;
        Ok(format!(
            "FilterResult(images=[{}], recommended={}, counts={})",
            names.join(", "),
            self.recommended.as_deref().unwrap_or("None"),
            self.counts.bind(py).repr()?
        ))
    }
}

/// filter(records, width=None, height=None, frames=1, spp=0, order="unspecified",
///        *, header=None, reference=None, albedo=None, normal=None,
///        aux_prefilter="accurate", threads=0, sigma_map=False, **config)
///
/// Runs the path-density filter and every selected method on `records`, a
/// C-contiguous (N, 6) float32 array (x, y, t, r, g, b), read in place. The
/// film is `width` × `height` × `frames` (or `header`, a dict as `read_dump`
/// returns). `config` is any FilterConfig field, named as in report.json's
/// "config" (k=10, sigma_color=100.0, white="auto", methods="median,clamp",
/// "all" or a list of names); the rest default as the command line's. `reference`
/// is a float array (H, W, 3) or (frames, H, W, 3); so are `albedo` and
/// `normal`, OIDN's auxiliary inputs and statmc's guide (as `--albedo`
/// and `--normal`; `aux_prefilter` as `--aux-prefilter`). The GIL is released while the filter runs; do not
/// write to `records` meanwhile.
#[pyfunction]
#[pyo3(signature = (records, width=None, height=None, frames=1, spp=0, order="unspecified", *, header=None, reference=None, albedo=None, normal=None, aux_prefilter="accurate", threads=0, sigma_map=false, **config))]
#[allow(clippy::too_many_arguments)]
fn filter(
    py: Python<'_>,
    records: &Bound<'_, PyAny>,
    width: Option<u32>,
    height: Option<u32>,
    frames: u32,
    spp: u32,
    order: &str,
    header: Option<&Bound<'_, PyDict>>,
    reference: Option<&Bound<'_, PyAny>>,
    albedo: Option<&Bound<'_, PyAny>>,
    normal: Option<&Bound<'_, PyAny>>,
    aux_prefilter: &str,
    threads: usize,
    sigma_map: bool,
    config: Option<&Bound<'_, PyDict>>,
) -> PyResult<FilterResult> {
    let array = records_of(records)?;
    let slice = as_records(&array);
    let h = match header {
        Some(d) => {
            if width.is_some() || height.is_some() {
                return Err(value_error("give either header or width and height"));
            }
            let get = |k: &str| -> PyResult<Bound<'_, PyAny>> {
                d.get_item(k)?
                    .ok_or_else(|| value_error(format!("header has no {k:?}")))
            };
            let order: String = get("order")?.extract()?;
            header_of(
                get("width")?.extract()?,
                get("height")?.extract()?,
                get("frames")?.extract()?,
                get("spp")?.extract()?,
                &order,
                slice.len(),
            )?
        }
        None => {
            let (Some(w), Some(ht)) = (width, height) else {
                return Err(value_error(
                    "filter needs the film's size: width= and height= (or header=)",
                ));
            };
            header_of(w, ht, frames, spp, order, slice.len())?
        }
    };
    let config = config_of(config)?;
    let reference = reference.map(|r| reference_of(r, &h)).transpose()?;
    let aux_prefilter = aux_prefilter.parse().map_err(value_error)?;
    let aux = aux_of(albedo, normal, &h)?.map(|a| a.with_prefilter(aux_prefilter));
    let threads = threads.min(pathdensity_core::par::max_threads());
    let exact_sigma = if sigma_map {
        ExactSigma::All
    } else {
        ExactSigma::None
    };
    let run = py
        .detach(|| {
            pipeline::run(
                slice,
                &h,
                &config,
                &RunOptions {
                    threads,
                    exact_sigma,
                    reference: reference.as_ref(),
                    progress: &Silent,
                    aux: aux.as_ref(),
                },
            )
        })
        .map_err(pipeline_error)?;
    // Records mapped by read_dump: refuse what was read from a file that
    // shrank meanwhile, as the command does.
    let mut base = records.getattr("base")?;
    while let Ok(array) = base.cast::<PyUntypedArray>() {
        base = array.getattr("base")?;
    }
    if let Ok(dump) = base.cast::<Dump>() {
        dump.get().reader.intact().map_err(os_error)?;
    }
    let images = PyDict::new(py);
    for e in &run.images {
        images.set_item(e.id().to_string(), image_array(py, &e.image)?)?;
    }
    Ok(FilterResult {
        images: images.unbind(),
        decisions: PyArray1::from_slice(py, &run.decisions).into_any().unbind(),
        counts: json_object(py, &run.counts)?.unbind(),
        metrics: json_object(py, &run.metrics)?.unbind(),
        recommended: pipeline::recommended(&run.images).map(|i| i.to_string()),
        denoiser: pipeline::denoiser(&run.config, aux.as_ref()),
        rejected: image_array(py, &run.removed)?.unbind(),
        sigma: match (&run.sigma_image, sigma_map) {
            (Some(s), true) => Some(image_array(py, s)?.unbind()),
            _ => None,
        },
        config: json_object(py, &run.config)?.unbind(),
        white: run.white,
        threads: run.threads,
        fallback_pixels: run.fallback_pixels,
        empty_pixels: run.empty_pixels,
        warnings: run.warnings,
    })
}

/// A mapped dump: the base of the records array `read_dump` returns, which
/// keeps the mapping alive.
#[pyclass(frozen, module = "pathdensity")]
struct Dump {
    reader: DumpReader,
}

#[pymethods]
impl Dump {
    /// The dump's path.
    #[getter]
    fn path(&self) -> PathBuf {
        self.reader.path().to_path_buf()
    }

    /// Raises OSError when the file shrank while it was mapped (the
    /// records past its new end then read as zeros).
    fn check_intact(&self) -> PyResult<()> {
        self.reader.intact().map_err(os_error)
    }

    fn __repr__(&self) -> String {
        format!("Dump({:?})", self.reader.path())
    }
}

fn header_dict<'py>(py: Python<'py>, h: &Header) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("width", h.width)?;
    d.set_item("height", h.height)?;
    d.set_item("frames", h.frames)?;
    d.set_item("spp", h.spp)?;
    d.set_item("sample_count", h.sample_count)?;
    d.set_item("order", order_name(h.order))?;
    d.set_item("scene", &h.scene)?;
    d.set_item("seed", h.seed)?;
    d.set_item("producer", &h.producer)?;
    Ok(d)
}

/// read_dump(path) -> (header, records)
///
/// Opens a dump as strictly as the command line does. `header` is a dict
/// (width, height, frames, spp, sample_count, order, scene, seed,
/// producer); `records` a read-only (N, 6) float32 array over the mapped
/// file, which its `base` (a `Dump`) keeps mapped.
#[pyfunction]
fn read_dump<'py>(
    py: Python<'py>,
    path: PathBuf,
) -> PyResult<(Bound<'py, PyDict>, Bound<'py, PyAny>)> {
    let reader = py.detach(|| DumpReader::open(&path)).map_err(os_error)?;
    let header = header_dict(py, reader.header())?;
    let dump = Bound::new(py, Dump { reader })?;
    let records = dump.get().reader.records();
    let array = if records.is_empty() {
        numpy::PyArray2::<f32>::zeros(py, [0, 6], false).into_any()
    } else {
        let floats: &[f32] = bytemuck::cast_slice(records);
        let view = ArrayView2::from_shape((records.len(), 6), floats).expect("6 floats a record");
        // SAFETY: the mapping lives as long as `dump`, which becomes the
        // array's base, and is never remapped.
        unsafe { PyArray2::borrow_from_array(&view, dump.clone().into_any()) }.into_any()
    };
    // The mapping is read-only: writing through the array would fault.
    let kwargs = PyDict::new(py);
    kwargs.set_item("write", false)?;
    array.call_method("setflags", (), Some(&kwargs))?;
    Ok((header, array))
}

/// write_dump(path, records, width, height, frames=1, spp=0, order="unspecified",
///            scene="", seed=0, producer=None, sample_count=None)
///
/// Writes `records` (a C-contiguous (N, 6) float32 array) as a dump, as the
/// command line writes one: under a temporary name renamed when complete,
/// never replacing a file that is not a dump. Takes `**header` from
/// `read_dump` (`sample_count`, if given, must be N).
#[pyfunction]
#[pyo3(signature = (path, records, width, height, frames=1, spp=0, order="unspecified", scene="", seed=0, producer=None, sample_count=None))]
#[allow(clippy::too_many_arguments)]
fn write_dump(
    py: Python<'_>,
    path: PathBuf,
    records: &Bound<'_, PyAny>,
    width: u32,
    height: u32,
    frames: u32,
    spp: u32,
    order: &str,
    scene: &str,
    seed: u64,
    producer: Option<String>,
    sample_count: Option<u64>,
) -> PyResult<()> {
    let array = records_of(records)?;
    let slice = as_records(&array);
    if let Some(n) = sample_count
        && n != slice.len() as u64
    {
        return Err(value_error(format!(
            "sample_count is {n}, but records holds {} records",
            slice.len()
        )));
    }
    let mut h = header_of(width, height, frames, spp, order, 0)?;
    h.scene = scene.to_owned();
    h.seed = seed;
    h.producer =
        producer.unwrap_or_else(|| format!("pathdensity python {}", env!("CARGO_PKG_VERSION")));
    py.detach(|| -> Result<(), pathdensity_format::Error> {
        let mut w = DumpWriter::create(&path, h)?;
        w.push_all(slice)?;
        w.finish()?;
        Ok(())
    })
    .map_err(os_error)
}

/// The path-density filter (DeCoro et al. 2010) on numpy arrays: `filter`,
/// `read_dump`, `write_dump`.
#[pymodule]
#[pyo3(name = "pathdensity")]
fn pathdensity_module(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_function(wrap_pyfunction!(filter, m)?)?;
    m.add_function(wrap_pyfunction!(read_dump, m)?)?;
    m.add_function(wrap_pyfunction!(write_dump, m)?)?;
    m.add_class::<FilterResult>()?;
    m.add_class::<Dump>()?;
    Ok(())
}
