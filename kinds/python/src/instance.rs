//! Building one instance: the context object its constructor gets (`ctx`), the class loaded from a
//! module of its own, the constructor called. A failure here becomes a model that fails the run
//! at its first step, naming what went wrong (the trait's `build` cannot fail).

use cohort_runtime::paper::Setup;
use cohort_runtime::rng::process_rng;
use cohort_wire::transport::Proc;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use rand::RngCore;

use crate::algorithm::{PyAlgorithm, Shape};
use crate::config::{PythonAlgorithmSetup, PythonPlantSetup};
use crate::interp::{generator, last_line, load_class, table_to_py, traceback};
use crate::plant::PyPlant;

/// The seed of a process's numpy generator: the first draw of its own Cohort stream, so it is the
/// same whether the process runs alone or as a thread of the reference run.
fn seed_of(setup: &Setup, p: Proc) -> u64 {
    process_rng(setup.scenario.seed, p).next_u64()
}

/// A `types.SimpleNamespace` of `fields`.
fn namespace<'py>(py: Python<'py>, fields: &Bound<'py, PyDict>) -> PyResult<Bound<'py, PyAny>> {
    py.import("types")?.getattr("SimpleNamespace")?.call((), Some(fields))
}

/// The fields every context has.
fn common<'py>(py: Python<'py>, setup: &Setup, seed: u64, rng: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("scenario", &setup.scenario.name)?;
    d.set_item("n_agents", setup.n_agents())?;
    d.set_item("dt_s", setup.scenario.dt_s)?;
    d.set_item("n_steps", setup.n_steps())?;
    d.set_item("seed", seed)?;
    d.set_item("rng", rng)?;
    Ok(d)
}

/// Construct `class` of `file` with `ctx`, the module loaded as `unique`.
fn construct<'py>(
    py: Python<'py>,
    (file, class, unique): (&std::path::Path, &str, &str),
    ctx: Bound<'py, PyAny>,
) -> Result<Bound<'py, PyAny>, String> {
    crate::interp::numpy(py)?;
    let cls = load_class(py, file, class, unique)?;
    cls.call1((ctx,)).map_err(|e| {
        tracing::error!("{class}(ctx) raised:\n{}", traceback(py, &e));
        format!("Python {class}(ctx) raised {}", last_line(py, &e))
    })
}

/// Agent `id`'s algorithm.
pub fn algorithm(a: &PythonAlgorithmSetup, setup: &Setup, id: u32) -> PyAlgorithm {
    let class = &a.config.class;
    let shape = Shape { name: class.clone(), command_len: a.command_len, share_values: a.config.share_values };
    Python::attach(|py| {
        let seed = seed_of(setup, Proc::Agent(id));
        let built = (|| {
            let rng = generator(py, seed)?;
            let ctx = (|| {
                let d = common(py, setup, seed, &rng)?;
                d.set_item("id", id)?;
                d.set_item("neighbours", PyList::new(py, &setup.agent(id).neighbours)?)?;
                d.set_item("params", table_to_py(py, &a.params_of(id))?)?;
                d.set_item("measurement", setup.plant.reading_names(setup, id))?;
                d.set_item("command", setup.plant.command_names())?;
                d.set_item("share_values", a.config.share_values)?;
                namespace(py, &d)
            })()
            .map_err(|e| format!("building the context: {}", last_line(py, &e)))?;
            let unique = format!("cohort_agent_{id}_{}", module_stem(&a.file));
            Ok::<_, String>((construct(py, (&a.file, class, &unique), ctx)?, rng))
        })();
        match built {
            Ok((obj, rng)) => PyAlgorithm::new(py, shape, obj, rng),
            Err(e) => PyAlgorithm::failed(shape, e),
        }
    })
}

/// The plant.
pub fn plant(p: &PythonPlantSetup, setup: &Setup) -> PyPlant {
    let class = &p.config.class;
    let sizes = (p.config.measurement.len(), p.config.command.len());
    Python::attach(|py| {
        let seed = seed_of(setup, Proc::Plant);
        let built = (|| {
            let rng = generator(py, seed)?;
            let ctx = (|| {
                let d = common(py, setup, seed, &rng)?;
                let agents = PyList::empty(py);
                for (i, keys) in p.agents.iter().enumerate() {
                    let id = i as u32 + 1;
                    let a = table_to_py(py, keys)?;
                    a.set_item("id", id)?;
                    a.set_item("neighbours", PyList::new(py, &setup.agent(id).neighbours)?)?;
                    agents.append(a)?;
                }
                d.set_item("agents", agents)?;
                d.set_item("params", table_to_py(py, &p.config.params)?)?;
                d.set_item("measurement", &p.config.measurement)?;
                d.set_item("command", &p.config.command)?;
                namespace(py, &d)
            })()
            .map_err(|e| format!("building the context: {}", last_line(py, &e)))?;
            let unique = format!("cohort_plant_{}", module_stem(&p.file));
            Ok::<_, String>((construct(py, (&p.file, class, &unique), ctx)?, rng))
        })();
        match built {
            Ok((obj, rng)) => PyPlant::new(py, class.clone(), sizes, obj, rng),
            Err(e) => PyPlant::failed(class.clone(), sizes.0, e),
        }
    })
}

/// The file's name without `.py`, as a module name may hold it.
fn module_stem(file: &std::path::Path) -> String {
    let stem = file.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    stem.chars().map(|c| if c.is_alphanumeric() { c } else { '_' }).collect()
}
