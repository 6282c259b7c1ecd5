//! `savsim._savsim`: the native half of the `savsim` Python package (python/savsim/ is the
//! other). It moves JSON rows in and Parquet bytes out, so that the Python side reads the
//! results with pyarrow, and it releases the GIL while runs run.

use pyo3::create_exception;
use pyo3::exceptions::PyException;
use pyo3::prelude::*;
use pyo3::types::PyBytes;

use savsim::batch::gen::{self, GenOptions};
use savsim::batch::{manifest, table};

create_exception!(
    _savsim,
    SavsimError,
    PyException,
    "An error savsim reports; its message says what and where."
);

fn error(message: impl std::fmt::Display) -> PyErr {
    SavsimError::new_err(message.to_string())
}

/// Run manifest rows (a JSON array of objects) as manifest rows `first_index..`, on `jobs`
/// threads (every core when None); the results as Parquet bytes. A run's failure is its row's
/// `error`; only rows that are not a manifest raise.
#[pyfunction]
#[pyo3(signature = (rows_json, first_index=0, jobs=None))]
fn run_manifest_json(
    py: Python<'_>,
    rows_json: &str,
    first_index: usize,
    jobs: Option<usize>,
) -> PyResult<Py<PyBytes>> {
    if jobs == Some(0) {
        return Err(error("jobs=0: give at least 1, or None for every core"));
    }
    let runs = manifest::parse_json(rows_json).map_err(|e| error(format!("manifest rows: {e}")))?;
    let parquet = py
        .detach(|| -> Result<Vec<u8>, String> {
            let rows = savsim::batch::run_rows(&runs, first_index, jobs, None, |_| {})
                .map_err(|e| e.to_string())?;
            let mut out = Vec::new();
            let settings = savsim::runs::table::Settings {
                command: "batch",
                manifest: String::new(),
                shard: savsim::runs::shard::Shard::WHOLE,
                more: vec![("via", "python".into())],
            };
            table::to_parquet(&rows, &settings, &mut out).map_err(|e| e.to_string())?;
            Ok(out)
        })
        .map_err(error)?;
    Ok(PyBytes::new(py, &parquet).unbind())
}

/// A manifest file's rows as a JSON array, paths made relative to its directory.
#[pyfunction]
fn load_manifest_json(path: &str) -> PyResult<String> {
    let runs = manifest::load(std::path::Path::new(path)).map_err(error)?;
    serde_json::to_string(&runs).map_err(error)
}

/// Generated encounters (as `savsim batch gen-encounters`) as a JSON array of rows.
#[pyfunction]
#[pyo3(signature = (n, seed=1, scene=None, mode="exact", duration_s=180.0, rate_hz=10.0, intruder_kind="dji"))]
fn gen_encounters_json(
    n: usize,
    seed: u64,
    scene: Option<String>,
    mode: &str,
    duration_s: f64,
    rate_hz: f64,
    intruder_kind: &str,
) -> PyResult<String> {
    let runs = gen::encounters(&GenOptions {
        n,
        seed,
        scene,
        mode: mode.into(),
        duration_s,
        rate_hz,
        intruder_kind: intruder_kind.into(),
    })
    .map_err(error)?;
    serde_json::to_string(&runs).map_err(error)
}

#[pymodule]
fn _savsim(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("SavsimError", m.py().get_type::<SavsimError>())?;
    m.add_function(wrap_pyfunction!(run_manifest_json, m)?)?;
    m.add_function(wrap_pyfunction!(load_manifest_json, m)?)?;
    m.add_function(wrap_pyfunction!(gen_encounters_json, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
