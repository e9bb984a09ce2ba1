//! Unit tests of the Python kinds: conversions, checkpoints (the numpy generator's state
//! included), and the section's checks. The process tests are in tests/system/python.rs.

use std::path::{Path, PathBuf};

use cohort_runtime::model::{AgentInput, Neighbour, ShareOut};
use cohort_runtime::paper::{Paper, Setup, load};
use pyo3::prelude::*;

use crate::convert::extend_floats;

/// The conversion into a fresh vector.
fn floats(obj: &Bound<'_, PyAny>, n: usize, what: impl Fn() -> String) -> Result<Vec<f64>, String> {
    let mut v = Vec::new();
    extend_floats(obj, n, what, &mut v).map(|_| v)
}

static KINDS: &[&dyn Paper] = &[&cohort_kinds_generic::Generic, &crate::Python];

fn examples() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/python")
}

fn scenario(dir: &Path, algorithm: &str) -> PathBuf {
    let text = std::fs::read_to_string(examples().join("consensus-ring.toml")).unwrap();
    let start = text.find("[algorithm]").unwrap();
    let end = text.find("[[agents]]").unwrap();
    let file = dir.join("s.toml");
    std::fs::write(&file, format!("{}{algorithm}\n\n{}", &text[..start], &text[end..])).unwrap();
    file
}

fn scratch(tag: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("cohort-kind-python-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

#[test]
fn returns_are_read_from_lists_tuples_and_arrays_and_refused_with_what_was_expected() {
    Python::attach(|py| {
        let np = py.import("numpy").expect("numpy (scripts/test installs it)");
        let eval = |code: &str| py.eval(&std::ffi::CString::new(code).unwrap(), None, None).unwrap();
        let what = || "C.share() command".to_string();
        assert_eq!(floats(&eval("[1.0, 2, 3.5]"), 3, what).unwrap(), vec![1.0, 2.0, 3.5]);
        assert_eq!(floats(&eval("(1.0, 2.0)"), 2, what).unwrap(), vec![1.0, 2.0]);
        let arr = np.call_method1("arange", (3.0,)).unwrap();
        assert_eq!(floats(&arr, 3, what).unwrap(), vec![0.0, 1.0, 2.0]);
        let strided = arr.get_item(pyo3::types::PySlice::new(py, 0, 3, 2)).unwrap();
        assert_eq!(floats(&strided, 2, what).unwrap(), vec![0.0, 2.0]);
        let e = floats(&eval("'abc'"), 3, what).unwrap_err();
        assert_eq!(e, "C.share() command: expected a sequence of 3 floats, got a str");
        let e = floats(&eval("[1.0]"), 3, what).unwrap_err();
        assert_eq!(e, "C.share() command: expected 3 values, got 1");
        let e = floats(&eval("[1.0, float('inf'), 0.0]"), 3, what).unwrap_err();
        assert_eq!(e, "C.share() command: value 1 is inf (not finite)");
    });
}

fn drive(a: &mut dyn cohort_runtime::model::Algorithm, from: u64, steps: u64) -> Vec<u64> {
    let mut bits = Vec::new();
    for k in from..from + steps {
        let mut out = ShareOut::default();
        let y = [k as f64 * 0.1, -0.2, 0.3];
        a.share(&AgentInput { k, t_s: k as f64 * 0.01, readings: &y }, &mut out);
        bits.extend(out.command.iter().chain(&out.values).map(|x| x.to_bits()));
        let nb = [0.5, 0.1, 0.0, 0.0, 0.0, 0.0];
        a.step(0.01, &[Neighbour { id: 2, values: &nb, age_steps: 0 }]);
        assert_eq!(a.take_failure(), None);
    }
    bits
}

#[test]
fn a_restored_python_agent_continues_bit_for_bit_its_generator_included() {
    let dir = scratch("ckpt");
    // An algorithm that draws from ctx.rng every step: the generator's state must be restored too.
    std::fs::write(
        dir.join("noisy.py"),
        "import pickle\nclass Noisy:\n    def __init__(self, ctx):\n        self.rng = ctx.rng\n        self.x = 0.0\n\
         \x20   def columns(self):\n        return ['x_m']\n    def share(self, k, t_s, y):\n        \
         return [self.x, 0.0, 0.0], [self.x, 0.0, 0.0, 0.0, 0.0, 0.0]\n    def step(self, dt_s, neighbours):\n        \
         self.x += self.rng.standard_normal()\n    def row(self):\n        return [self.x]\n    def save_state(self):\n        \
         return pickle.dumps(self.x)\n    def restore_state(self, state):\n        self.x = pickle.loads(state)\n",
    )
    .unwrap();
    for (module, class) in [(examples().join("consensus.py"), "ConsensusFormation"), (dir.join("noisy.py"), "Noisy")] {
        let params = "[algorithm.params]\nformation_radius_m = 10.0\nkp_per_s2 = 0.5\nkd_per_s = 1.5\n\
                      observer_l1_per_s = 6.0\nobserver_l2_per_s2 = 9.0\n";
        let section = format!(
            "[algorithm]\nkind = \"python\"\nmodule = {module:?}\nclass = \"{class}\"\nshare_values = 6\n{params}"
        );
        let setup: Setup =
            load(&scenario(&dir, &section), &Default::default(), KINDS).unwrap_or_else(|e| panic!("{e}"));
        let mut a = setup.algorithm.build(&setup, 1);
        drive(a.as_mut(), 0, 30);
        let saved = a.save_state();
        let straight = drive(a.as_mut(), 30, 30);
        let mut b = setup.algorithm.build(&setup, 1);
        b.restore_state(&saved).unwrap();
        assert_eq!(b.save_state(), saved, "{class}: the restored state encodes to the same bytes");
        assert_eq!(drive(b.as_mut(), 30, 30), straight, "{class}: after restoring, the same shares bit for bit");
        assert!(b.restore_state(&saved[..4]).unwrap_err().to_string().contains("shorter than its header"));
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn the_sections_checks_name_the_key_path() {
    let dir = scratch("checks");
    let module = examples().join("consensus.py");
    let cases = [
        (
            format!(
                "module = {module:?}\nclass = \"ConsensusFormation\"\nshare_values = 6\n[algorithm.per_agent.9]\nkp_per_s2 = 1.0\n"
            ),
            "algorithm.per_agent.9",
        ),
        ("module = \"consensus.txt\"\nclass = \"C\"\nshare_values = 6\n".to_string(), "expected a Python file (.py)"),
        (format!("module = {module:?}\nclass = \"not a name\"\nshare_values = 6\n"), "not a Python class name"),
        (format!("module = {module:?}\nclass = \"ConsensusFormation\"\n"), "share_values"),
    ];
    for (body, expect) in cases {
        let e = load(&scenario(&dir, &format!("[algorithm]\nkind = \"python\"\n{body}")), &Default::default(), KINDS)
            .map(|_| ())
            .unwrap_err()
            .to_string();
        assert!(e.contains(expect), "expected {expect:?} in:\n{e}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_step_that_takes_three_arguments_gets_each_shares_age() {
    let dir = scratch("ages");
    std::fs::write(
        dir.join("aged.py"),
        "class Aged:\n    def __init__(self, ctx):\n        self.age = -1.0\n    def columns(self):\n        \
         return ['age_steps_1']\n    def share(self, k, t_s, y):\n        return [0.0, 0.0, 0.0], [0.0] * 6\n    \
         def step(self, dt_s, neighbours, ages):\n        self.age = float(ages[2])\n    def row(self):\n        \
         return [self.age]\n    def save_state(self):\n        return b''\n    def restore_state(self, state):\n        pass\n",
    )
    .unwrap();
    let section = format!(
        "[algorithm]\nkind = \"python\"\nmodule = {:?}\nclass = \"Aged\"\nshare_values = 6\n",
        dir.join("aged.py")
    );
    let setup: Setup = load(&scenario(&dir, &section), &Default::default(), KINDS).unwrap_or_else(|e| panic!("{e}"));
    let mut a = setup.algorithm.build(&setup, 1);
    let mut out = ShareOut::default();
    a.share(&AgentInput { k: 0, t_s: 0.0, readings: &[0.0, 0.0, 0.0] }, &mut out);
    a.step(0.01, &[Neighbour { id: 2, values: &[0.0; 6], age_steps: 3 }]);
    assert_eq!(a.take_failure(), None);
    let mut row = Vec::new();
    a.row(&mut row);
    assert_eq!(row, [3.0]);
    let _ = std::fs::remove_dir_all(&dir);
}
