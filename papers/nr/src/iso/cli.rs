//! Parsing of seed 003's command-line values (`orchestrator train nr-iso`, `orchestrator nr
//! campaign`): every error names the flag, the value and the reason (the commands exit 2 on it).

use std::ops::Range;

use crate::iso::config::Method;
use crate::iso::dynamics::constants::ISO_SET_SIZE;

/// `A..B`: ISOs A to B − 1 of the set (0 ≤ A < B ≤ 300).
pub fn isos(flag: &str, s: &str) -> Result<Range<u32>, String> {
    let bad = |why: &str| format!("{flag} {s:?}: {why}");
    let (a, b) = s.split_once("..").ok_or_else(|| bad("expected A..B, e.g. 200..300"))?;
    let a: u32 = a.trim().parse().map_err(|_| bad("A is not a whole number"))?;
    let b: u32 = b.trim().parse().map_err(|_| bad("B is not a whole number"))?;
    if a >= b {
        return Err(bad("empty range (A must be below B)"));
    }
    if b > ISO_SET_SIZE {
        return Err(bad(&format!("the set holds ISOs 0..{ISO_SET_SIZE}")));
    }
    Ok(a..b)
}

/// A comma list of method names, each once.
pub fn methods(flag: &str, s: &str) -> Result<Vec<Method>, String> {
    let mut out = Vec::new();
    for name in s.split(',').map(str::trim) {
        let m = Method::ALL.into_iter().find(|m| m.name() == name).ok_or_else(|| {
            format!("{flag}: unknown method {name:?} (expected {})", Method::ALL.map(Method::name).join(", "))
        })?;
        if out.contains(&m) {
            return Err(format!("{flag}: {name:?} given twice"));
        }
        out.push(m);
    }
    Ok(out)
}

/// A comma list of numbers for which `ok` holds (`why` says what it wants), or `none` (empty).
pub fn numbers(flag: &str, s: &str, ok: impl Fn(f64) -> bool, why: &str) -> Result<Vec<f64>, String> {
    if s.trim() == "none" {
        return Ok(Vec::new());
    }
    let mut out = Vec::new();
    for item in s.split(',').map(str::trim) {
        let x: f64 = item.parse().map_err(|_| format!("{flag}: {item:?} is not a number (or give `none`)"))?;
        if !(x.is_finite() && ok(x)) {
            return Err(format!("{flag}: {item}: {why}"));
        }
        if out.contains(&x) {
            return Err(format!("{flag}: {item} given twice"));
        }
        out.push(x);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_values_are_refused_naming_flag_and_value() {
        assert_eq!(isos("--isos", "200..300").unwrap(), 200..300);
        for bad in ["200", "a..3", "5..5", "0..301"] {
            let e = isos("--isos", bad).unwrap_err();
            assert!(e.contains("--isos") && e.contains(bad), "{e}");
        }
        assert_eq!(methods("--methods", "pd,nmpc").unwrap(), vec![Method::Pd, Method::Nmpc]);
        assert!(methods("--methods", "pd,magic").unwrap_err().contains("magic"));
        assert!(methods("--methods", "pd,pd").unwrap_err().contains("twice"));
        let pos = |x: f64| x > 0.0;
        assert_eq!(numbers("--dts", "300, 600", pos, "must be > 0").unwrap(), vec![300.0, 600.0]);
        assert!(numbers("--dts", "none", pos, "").unwrap().is_empty());
        assert!(numbers("--dts", "-1", pos, "must be > 0").unwrap_err().contains("must be > 0"));
        assert!(numbers("--dts", "x", pos, "").unwrap_err().contains("\"x\""));
        assert!(numbers("--dts", "nan", pos, "finite").unwrap_err().contains("finite"));
    }
}
