//! Monte Carlo dispersions: `[[dispersions]]` in a scenario (or a file of them) say which keys a
//! campaign draws, from which distribution, and which draws are correlated.
//!
//! ```toml
//! [[dispersions]]
//! key = "agents[2].mass_kg"          # any key path the scenario sets
//! dist = "truncated-normal"          # normal, truncated-normal, uniform, log-uniform,
//! sigma_rel = 0.05                   # uniform-int, choice
//! low = 20.0
//! high = 30.0
//! group = "masses"                   # optional: correlated with the group's other members
//! correlation = 0.8
//! ```
//!
//! - A key must be one the scenario (after command-line overrides) sets: a dispersion changes a
//!   value, it never adds one, so a misspelt key is an error and never a silent skip. Its nominal
//!   value gives the type: a float takes any distribution, a whole number `uniform-int` or `choice`,
//!   a string or a boolean `choice`, an array of numbers is drawn component by component (each
//!   parameter one number for all components or one per component). `mean` defaults to the nominal
//!   value; `sigma_rel` is σ as a fraction of the nominal's magnitude.
//! - **Draws**: case `i` of a campaign with seed `S` draws from its own ChaCha8 stream
//!   (seeded from `S`, stream `i`), so a case's values depend on `(S, i)` only — not on the number
//!   of workers, nor on which cases ran before. Each drawn number is a quantile of one uniform
//!   (see [`law`]); in a correlation group the uniforms come from a Gaussian copula: the group draws
//!   one standard normal `g`, a member with correlation `ρ` uses `√ρ·g + √(1−ρ)·e` (its own `e`), so
//!   two members correlate by `√(ρ₁ρ₂)` in normal space while each keeps its own distribution.
//! - A drawn scenario is validated like a hand-written one by the caller (bounds are the
//!   scenario's own checks); the campaign draws and validates every case before it runs one.

pub mod keypath;
pub mod law;
pub mod spec;

use rand::{RngCore, SeedableRng};
use rand_chacha::ChaCha8Rng;

pub use keypath::KeyPath;
pub use spec::{Dispersion, RawDispersion};

use crate::error::Problem;

/// The top-level key of the dispersions in a scenario or dispersions file.
pub const SECTION: &str = "dispersions";

/// A campaign's checked dispersions.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Dispersions {
    pub items: Vec<Dispersion>,
}

impl Dispersions {
    /// Read `[[dispersions]]` (the section's raw value) and check it against `nominal`, the
    /// scenario's table without its dispersions; every problem at once.
    pub fn parse(raw: toml::Value, nominal: &toml::Table) -> Result<Self, Vec<Problem>> {
        let mut problems = Vec::new();
        let Some(entries) = crate::parse::section::<Vec<RawDispersion>>(raw, SECTION, &mut problems) else {
            return Err(problems);
        };
        // Each checked entry with its index in the file (problems name that).
        let mut checked: Vec<(usize, Dispersion)> = Vec::new();
        for (k, r) in entries.iter().enumerate() {
            match spec::check(k, r, nominal) {
                Ok(d) => checked.push((k, d)),
                Err(p) => problems.extend(p),
            }
        }
        for (n, (k, d)) in checked.iter().enumerate() {
            if let Some((j, e)) = checked[..n].iter().find(|(_, e)| overlaps(&e.key, &d.key)) {
                problems.push(Problem::new(
                    format!("{SECTION}[{k}].key"),
                    Some(format!("{:?}", d.key.to_string())),
                    format!("overlaps {SECTION}[{j}] ({}): a value is drawn once", e.key),
                ));
            }
        }
        if entries.is_empty() {
            problems.push(Problem::new(SECTION, None, "empty: a campaign needs at least one dispersion"));
        }
        let items = checked.into_iter().map(|(_, d)| d).collect();
        if problems.is_empty() { Ok(Self { items }) } else { Err(problems) }
    }

    pub fn is_empty(&self) -> bool {
        self.items.is_empty()
    }

    /// The drawn values' names, in draw order: a scalar's key path, a vector's `key[i]`.
    pub fn columns(&self) -> Vec<String> {
        let mut out = Vec::new();
        for d in &self.items {
            if d.vector {
                out.extend((0..d.laws.len()).map(|i| format!("{}[{i}]", d.key)));
            } else {
                out.push(d.key.to_string());
            }
        }
        out
    }

    /// Case `case`'s values, one per column (see the module docs for the streams).
    pub fn draw(&self, seed: u64, case: u64) -> Vec<toml::Value> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        rng.set_stream(case);
        let mut uniform = move || ((rng.next_u64() >> 11) as f64 + 0.5) * (1.0 / (1u64 << 53) as f64);
        // The groups' common factors first, in order of first appearance.
        let mut groups: Vec<(&str, f64)> = Vec::new();
        for d in &self.items {
            if let Some(g) = d.group.as_deref()
                && !groups.iter().any(|(n, _)| *n == g)
            {
                groups.push((g, law::phi_inv(uniform())));
            }
        }
        let mut out = Vec::new();
        for d in &self.items {
            let common = d.group.as_deref().and_then(|g| groups.iter().find(|(n, _)| *n == g)).map(|(_, z)| *z);
            for l in &d.laws {
                let u = match common {
                    None => uniform(),
                    Some(z) => {
                        let rho = d.correlation;
                        let mixed = rho.sqrt() * z + (1.0 - rho).sqrt() * law::phi_inv(uniform());
                        law::phi(mixed).clamp(f64::MIN_POSITIVE, 1.0 - f64::EPSILON / 2.0)
                    }
                };
                out.push(l.quantile(u));
            }
        }
        out
    }

    /// Write `values` (from [`Self::draw`]) into `table`.
    pub fn apply(&self, table: &mut toml::Table, values: &[toml::Value]) {
        let mut next = values.iter();
        for d in &self.items {
            let slot = d.key.get_mut(table).expect("a checked dispersion's key is in the table it was checked on");
            if d.vector {
                let arr = slot.as_array_mut().expect("a vector key holds an array");
                for x in arr.iter_mut().take(d.laws.len()) {
                    *x = next.next().expect("one value per component").clone();
                }
            } else {
                *slot = next.next().expect("one value per dispersion").clone();
            }
        }
    }

    /// The dispersion whose key a problem's path is at or under, if one is.
    pub fn blame(&self, problem_path: &str) -> Option<usize> {
        self.items.iter().position(|d| {
            let k = d.key.to_string();
            problem_path == k || problem_path.strip_prefix(&k).is_some_and(|r| r.starts_with('.') || r.starts_with('['))
        })
    }
}

/// One key path at or under the other.
fn overlaps(a: &KeyPath, b: &KeyPath) -> bool {
    let n = a.0.len().min(b.0.len());
    a.0[..n] == b.0[..n]
}

/// Take the dispersions out of a scenario's table (a launch runs the nominal scenario).
pub fn split(table: &mut toml::Table) -> Option<toml::Value> {
    table.remove(SECTION)
}

#[cfg(test)]
mod tests;
