//! Shared by the build scripts of every package whose binaries or tests link libpython (this
//! crate, the registry, `agent`, `plant`, `orchestrator`): records the directory of the
//! libpython pyo3 linked as the run path, so the loader finds that library (and with it that
//! installation's `site-packages`, where `pip install numpy` put numpy) rather than another
//! `libpython3.x.so` on the system library path, or none.

pub fn emit() {
    let config = pyo3_build_config::get();
    if let Some(dir) = config.lib_dir() {
        println!("cargo:rustc-link-arg=-Wl,-rpath,{dir}");
    }
    if let Some(exe) = config.executable() {
        println!("cargo:rustc-env=COHORT_PYTHON_EXE={exe}");
    }
}
