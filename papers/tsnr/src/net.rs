//! The net of the tethered space net robot: a square spring–damper mesh (eq. (4)) whose four
//! corners are the maneuverable units (MUs), moving relative to a target on a circular orbit.
//!
//! Model (papers/tsnr/README.md, "our choices" where the paper is silent):
//! - `nodes_per_side` × `nodes_per_side` nodes (default 11 × 11, so 10 × 10 meshes), structural
//!   edges between grid neighbours only (2·n·(n−1) = 220 edges), rest length l_n (0.5 m).
//! - Edge force along the edge, eq. (4): f = (EA/l_n)·Δl + c·l̇ while the edge is stretched
//!   (Δl = l − l_n ≥ 0), zero while slack, and the total clipped at zero: a tether pulls, it never
//!   pushes, so a fast-closing stretched edge goes limp instead of pushing its nodes apart.
//! - Masses: the net's mass (1 kg) is spread evenly over the non-corner nodes (117 of them, 8.55 g
//!   each). The corner nodes *are* the MUs and carry the MU mass (10 kg) only: by that choice the
//!   net has no mass at the corners, so there is no "net share" to add to an MU.
//! - Relative motion: the linearised Clohessy–Wiltshire (Hill) equations in the target's LVLH
//!   frame (x radial, y along-track, z cross-track), per node of mass m with applied force f:
//!   ẍ − 2nẏ − 3n²x = f_x/m, ÿ + 2nẋ = f_y/m, z̈ + n²z = f_z/m ([`crate::cw`]). The paper's
//!   printed y-equation (2) has a sign/factor slip; these are the standard equations.
//! - Grid layout and MU numbering (the paper's start states: MU1 (+y, +z), MU2 (−y, +z),
//!   MU3 (+y, −z), MU4 (−y, −z)): node (row, col) has index row·n + col; MU1 is (0, 0), MU2
//!   (0, n−1), MU3 (n−1, 0), MU4 (n−1, n−1). Along the net's edges MU1 is adjacent to MU2 and MU3,
//!   MU4 to MU2 and MU3; MU1–MU4 and MU2–MU3 are diagonals ([`adjacent_mus`]).
//!
//! Integration: classic RK4 with fixed sub-steps of at most `substep_s`, thrust held (zero-order
//! hold). The state ([`NetState`]) is kept apart from the model and its scratch buffers ([`Net`]),
//! so callers can copy, compare and restore states freely; [`Net::advance`] allocates nothing.
//!
//! Stability of the sub-step. With k = EA/l_n = 400 N/m and the lightest node m = 8.55 g, one
//! isolated stretched edge between two free nodes rings at √(2k/m) ≈ 306 rad/s, but the taut mesh's
//! highest mode is the alternating ("zig-zag") mode of a line of nodes, ω = 2√(k/m) ≈ 433 rad/s
//! (the prestress of a taut mesh adds a factor √(1 + strain), < 5 % below 10 % strain). Explicit
//! RK4 is stable for an undamped oscillator while hω ≤ 2√2 ≈ 2.83, so h must stay below
//! ≈ 6.5 ms (not the 2.8/306 ≈ 9 ms a single edge suggests). The damper adds real eigenvalues up
//! to ≈ 4c/m ≈ 47 1/s, far inside RK4's real-axis limit (2.79/h). [`NetParams::max_stable_substep_s`]
//! allows for 10 % strain: 2√2/(433·√1.1) ≈ 6.2 ms, which validation enforces; the default 1 ms is
//! 6× below it. A test checks ω_max against the power-iterated spectrum of the linearised taut
//! mesh (2 % and 8 % stretch). Accuracy is another matter: each
//! edge's stiffness jumps where it goes taut, so RK4 loses its order there: a free undamped mesh
//! ringing with edges going slack and taut drifts in energy by 7.6e-3 over 10 s at 1 ms, and
//! conserving it to 1e-6 needs ≈ 0.02 ms (the test below). With the default damping the same
//! state loses 61 % of its energy in those 10 s, so at 1 ms the integration error is ≈ 1 % of
//! what the dampers remove: adequate for the closed loop.

use thiserror::Error;

use crate::cw::{free_accel_mps2, mean_motion_rad_s};

/// Number of MUs: the four corners of the net.
pub const N_MU: usize = 4;

/// The net's physical parameters and the integrator's sub-step. Check with [`NetParams::validate`]
/// ([`Net::new`] does).
#[derive(Debug, Clone, PartialEq)]
pub struct NetParams {
    /// Nodes along each side (≥ 3, so that the net has non-corner nodes).
    pub nodes_per_side: usize,
    /// Rest length l_n of every edge, m.
    pub edge_rest_m: f64,
    /// Mass of the net, spread evenly over the non-corner nodes, kg.
    pub net_mass_kg: f64,
    /// Mass of each MU (a corner node), kg.
    pub mu_mass_kg: f64,
    /// Axial stiffness EA of an edge, N (spring constant EA/l_n).
    pub ea_n: f64,
    /// Damping coefficient c of an edge, N·s/m.
    pub damping_n_s_per_m: f64,
    /// Radius r₀ of the target's circular orbit, m.
    pub orbit_radius_m: f64,
    /// Longest RK4 sub-step, s: a call to [`Net::advance`] over dt is split into
    /// ceil(dt / substep_s) equal sub-steps.
    pub substep_s: f64,
}

impl Default for NetParams {
    /// Our choices, papers/tsnr/README.md.
    fn default() -> Self {
        Self {
            nodes_per_side: 11,
            edge_rest_m: 0.5,
            net_mass_kg: 1.0,
            mu_mass_kg: 10.0,
            ea_n: 200.0,
            damping_n_s_per_m: 0.1,
            orbit_radius_m: 42_164e3,
            substep_s: 1e-3,
        }
    }
}

/// A parameter that cannot describe a net.
#[derive(Debug, Clone, PartialEq, Error)]
#[error("net parameter {name} = {value}: {reason}")]
pub struct NetError {
    pub name: &'static str,
    pub value: String,
    pub reason: String,
}

/// Strain up to which [`NetParams::max_stable_substep_s`] guarantees stability (the prestress of
/// a taut mesh raises its highest frequency by √(1 + strain)).
pub const STABILITY_STRAIN_ALLOWANCE: f64 = 0.1;

/// |hλ| at which classic RK4 stops being stable on the imaginary axis (2√2).
const RK4_IMAG_LIMIT: f64 = 2.0 * std::f64::consts::SQRT_2;
/// ... and on the negative real axis (the root of 1 + z + z²/2 + z³/6 + z⁴/24 = 1 near −2.785).
const RK4_REAL_LIMIT: f64 = 2.785;

impl NetParams {
    /// Every parameter finite and in range; the first problem found.
    pub fn validate(&self) -> Result<(), NetError> {
        let fail = |name, value: f64, reason: &str| {
            Err(NetError { name, value: format!("{value:?}"), reason: reason.to_string() })
        };
        if self.nodes_per_side < 3 || self.nodes_per_side > 64 {
            return Err(NetError {
                name: "nodes_per_side",
                value: self.nodes_per_side.to_string(),
                reason: "must be 3..=64 (corners are MUs, so the net needs non-corner nodes)".into(),
            });
        }
        for (name, v) in [
            ("edge_rest_m", self.edge_rest_m),
            ("net_mass_kg", self.net_mass_kg),
            ("mu_mass_kg", self.mu_mass_kg),
            ("ea_n", self.ea_n),
            ("orbit_radius_m", self.orbit_radius_m),
            ("substep_s", self.substep_s),
        ] {
            if !v.is_finite() || v <= 0.0 {
                return fail(name, v, "must be a finite number > 0");
            }
        }
        if !self.damping_n_s_per_m.is_finite() || self.damping_n_s_per_m < 0.0 {
            return fail("damping_n_s_per_m", self.damping_n_s_per_m, "must be a finite number ≥ 0");
        }
        let limit = self.max_stable_substep_s();
        if self.substep_s > limit {
            return Err(NetError {
                name: "substep_s",
                value: format!("{:?}", self.substep_s),
                reason: format!(
                    "above the explicit-RK4 stability limit {limit:.3e} s of this net (highest mode \
                     {:.1} rad/s)",
                    self.highest_frequency_rad_s()
                ),
            });
        }
        Ok(())
    }

    /// Edge spring constant EA/l_n, N/m.
    pub fn stiffness_n_per_m(&self) -> f64 {
        self.ea_n / self.edge_rest_m
    }

    /// Mass of each non-corner node, kg.
    pub fn net_node_mass_kg(&self) -> f64 {
        let n = self.nodes_per_side;
        self.net_mass_kg / (n * n - N_MU) as f64
    }

    /// Mean motion n of the target's orbit, rad/s.
    pub fn mean_motion_rad_s(&self) -> f64 {
        mean_motion_rad_s(self.orbit_radius_m)
    }

    /// Highest natural frequency of the taut mesh, rad/s: the zig-zag mode of a line of the
    /// lightest nodes, 2√(k/m), raised by √(1 + [`STABILITY_STRAIN_ALLOWANCE`]) for prestress.
    pub fn highest_frequency_rad_s(&self) -> f64 {
        let m = self.net_node_mass_kg().min(self.mu_mass_kg);
        2.0 * (self.stiffness_n_per_m() * (1.0 + STABILITY_STRAIN_ALLOWANCE) / m).sqrt()
    }

    /// Longest stable RK4 sub-step, s: min(2√2/ω_max, 2.785/(4c/m)), the oscillatory and the
    /// damping limits (see the module notes).
    pub fn max_stable_substep_s(&self) -> f64 {
        let m = self.net_node_mass_kg().min(self.mu_mass_kg);
        let osc = RK4_IMAG_LIMIT / self.highest_frequency_rad_s();
        let damp_rate = 4.0 * self.damping_n_s_per_m / m;
        if damp_rate > 0.0 { osc.min(RK4_REAL_LIMIT / damp_rate) } else { osc }
    }

    /// Number of equal sub-steps `advance` uses over `dt_s`.
    pub fn substeps(&self, dt_s: f64) -> usize {
        // The 1e-9 keeps 0.1 / 1e-3 from becoming 101 through rounding.
        ((dt_s / self.substep_s) * (1.0 - 1e-9)).ceil().max(1.0) as usize
    }
}

/// The two MUs adjacent to MU `mu` (1..=4) along the net's edges, in ascending id order.
pub fn adjacent_mus(mu: u32) -> [u32; 2] {
    match mu {
        1 => [2, 3],
        2 => [1, 4],
        3 => [1, 4],
        4 => [2, 3],
        _ => panic!("MU ids are 1..=4, got {mu}"),
    }
}

/// Positions and velocities of every node in the target's LVLH frame, node (row, col) at index
/// row·n + col.
#[derive(Debug, Clone, PartialEq)]
pub struct NetState {
    pub r_lvlh_m: Vec<[f64; 3]>,
    pub v_lvlh_mps: Vec<[f64; 3]>,
}

/// The energy of a net state, J. With no damping and no thrust, [`NetEnergy::total_j`] is
/// conserved: it is the Jacobi integral of CW motion (kinetic energy in the rotating frame plus
/// the effective potential m(−3/2 n²x² + 1/2 n²z²); the Coriolis force does no work) plus the
/// elastic energy of the stretched edges.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NetEnergy {
    /// Σ ½ m |v|² (velocities relative to the LVLH frame).
    pub kinetic_j: f64,
    /// Σ over stretched edges ½ (EA/l_n) Δl².
    pub elastic_j: f64,
    /// Σ m(−3/2 n²x² + 1/2 n²z²).
    pub cw_potential_j: f64,
}

impl NetEnergy {
    pub fn total_j(&self) -> f64 {
        self.kinetic_j + self.elastic_j + self.cw_potential_j
    }
}

/// Force magnitude of one edge along its unit vector (pulling its two nodes together), N: eq. (4)
/// with the slack case and the clip at zero. `length_m` is the current length, `rate_mps` its
/// time derivative l̇.
#[inline]
pub fn edge_tension_n(ea_n: f64, rest_m: f64, damping_n_s_per_m: f64, length_m: f64, rate_mps: f64) -> f64 {
    let stretch = length_m - rest_m;
    if stretch < 0.0 {
        return 0.0;
    }
    (ea_n / rest_m * stretch + damping_n_s_per_m * rate_mps).max(0.0)
}

/// The net model: topology, masses and the integrator's scratch buffers.
#[derive(Debug, Clone)]
pub struct Net {
    params: NetParams,
    n_rad_s: f64,
    k_n_per_m: f64,
    edges: Vec<[usize; 2]>,
    mass_kg: Vec<f64>,
    inv_mass: Vec<f64>,
    corners: [usize; N_MU],
    scratch: Scratch,
}

/// RK4 work space, one entry per node.
#[derive(Debug, Clone, Default)]
struct Scratch {
    r: Vec<[f64; 3]>,
    v: Vec<[f64; 3]>,
    acc: Vec<[f64; 3]>,
    sum_dr: Vec<[f64; 3]>,
    sum_dv: Vec<[f64; 3]>,
}

impl Net {
    pub fn new(params: NetParams) -> Result<Self, NetError> {
        params.validate()?;
        let n = params.nodes_per_side;
        let idx = |row: usize, col: usize| row * n + col;
        let mut edges = Vec::with_capacity(2 * n * (n - 1));
        for row in 0..n {
            for col in 0..n {
                if col + 1 < n {
                    edges.push([idx(row, col), idx(row, col + 1)]);
                }
                if row + 1 < n {
                    edges.push([idx(row, col), idx(row + 1, col)]);
                }
            }
        }
        let corners = [idx(0, 0), idx(0, n - 1), idx(n - 1, 0), idx(n - 1, n - 1)];
        let mut mass_kg = vec![params.net_node_mass_kg(); n * n];
        for c in corners {
            mass_kg[c] = params.mu_mass_kg;
        }
        let inv_mass = mass_kg.iter().map(|m| 1.0 / m).collect();
        let zeros = vec![[0.0; 3]; n * n];
        let scratch =
            Scratch { r: zeros.clone(), v: zeros.clone(), acc: zeros.clone(), sum_dr: zeros.clone(), sum_dv: zeros };
        Ok(Self {
            n_rad_s: params.mean_motion_rad_s(),
            k_n_per_m: params.stiffness_n_per_m(),
            params,
            edges,
            mass_kg,
            inv_mass,
            corners,
            scratch,
        })
    }

    pub fn params(&self) -> &NetParams {
        &self.params
    }
    pub fn n_nodes(&self) -> usize {
        self.mass_kg.len()
    }
    /// Each edge's two node indices.
    pub fn edges(&self) -> &[[usize; 2]] {
        &self.edges
    }
    pub fn node_mass_kg(&self) -> &[f64] {
        &self.mass_kg
    }
    /// Node index of MU 1..=4 (array index MU id − 1).
    pub fn corner_nodes(&self) -> [usize; N_MU] {
        self.corners
    }

    /// The folded net at release: the grid mapped bilinearly onto the four MUs' positions (and
    /// velocities), so the default start (a 1.5 m square) packs the 5 m net with every edge slack.
    pub fn folded_state(&self, mu_r_lvlh_m: &[[f64; 3]; N_MU], mu_v_lvlh_mps: &[[f64; 3]; N_MU]) -> NetState {
        let n = self.params.nodes_per_side;
        let blend = |p: &[[f64; 3]; N_MU], row: usize, col: usize| {
            let (a, b) = (row as f64 / (n - 1) as f64, col as f64 / (n - 1) as f64);
            let w = [(1.0 - a) * (1.0 - b), (1.0 - a) * b, a * (1.0 - b), a * b];
            std::array::from_fn(|ax| (0..N_MU).map(|i| w[i] * p[i][ax]).sum::<f64>())
        };
        let mut state = NetState { r_lvlh_m: Vec::with_capacity(n * n), v_lvlh_mps: Vec::with_capacity(n * n) };
        for row in 0..n {
            for col in 0..n {
                state.r_lvlh_m.push(blend(mu_r_lvlh_m, row, col));
                state.v_lvlh_mps.push(blend(mu_v_lvlh_mps, row, col));
            }
        }
        // Exact corners, whatever the rounding of the blend.
        for (i, &c) in self.corners.iter().enumerate() {
            state.r_lvlh_m[c] = mu_r_lvlh_m[i];
            state.v_lvlh_mps[c] = mu_v_lvlh_mps[i];
        }
        state
    }

    /// Integrate `state` over `dt_s` with each MU's thrust (N, LVLH) held; returns the number of
    /// RK4 sub-steps taken.
    pub fn advance(&mut self, state: &mut NetState, dt_s: f64, thrust_n: &[[f64; 3]; N_MU]) -> usize {
        assert_eq!(state.r_lvlh_m.len(), self.n_nodes(), "state of another net");
        let steps = self.params.substeps(dt_s);
        let h = dt_s / steps as f64;
        for _ in 0..steps {
            self.rk4_step(state, h, thrust_n);
        }
        steps
    }

    fn rk4_step(&mut self, state: &mut NetState, h: f64, thrust_n: &[[f64; 3]; N_MU]) {
        // The stage derivatives are summed on the fly (weights 1, 2, 2, 1) instead of being kept.
        let mut s = std::mem::take(&mut self.scratch);
        let nn = self.n_nodes();
        self.accelerations(&state.r_lvlh_m, &state.v_lvlh_mps, thrust_n, &mut s.acc);
        for i in 0..nn {
            let (r0, v0, a) = (state.r_lvlh_m[i], state.v_lvlh_mps[i], s.acc[i]);
            s.sum_dr[i] = v0;
            s.sum_dv[i] = a;
            s.r[i] = std::array::from_fn(|ax| r0[ax] + 0.5 * h * v0[ax]);
            s.v[i] = std::array::from_fn(|ax| v0[ax] + 0.5 * h * a[ax]);
        }
        // Stages 2 and 3: the derivative at the trial point (s.r, s.v), then the next trial point.
        for c_next in [0.5, 1.0] {
            self.accelerations(&s.r, &s.v, thrust_n, &mut s.acc);
            for i in 0..nn {
                let (r0, v0, v, a) = (state.r_lvlh_m[i], state.v_lvlh_mps[i], s.v[i], s.acc[i]);
                for ax in 0..3 {
                    s.sum_dr[i][ax] += 2.0 * v[ax];
                    s.sum_dv[i][ax] += 2.0 * a[ax];
                    s.r[i][ax] = r0[ax] + c_next * h * v[ax];
                    s.v[i][ax] = v0[ax] + c_next * h * a[ax];
                }
            }
        }
        self.accelerations(&s.r, &s.v, thrust_n, &mut s.acc);
        for i in 0..nn {
            for ax in 0..3 {
                state.r_lvlh_m[i][ax] += h / 6.0 * (s.sum_dr[i][ax] + s.v[i][ax]);
                state.v_lvlh_mps[i][ax] += h / 6.0 * (s.sum_dv[i][ax] + s.acc[i][ax]);
            }
        }
        self.scratch = s;
    }

    /// Every node's acceleration: edge forces, thrust on the corners, CW terms.
    fn accelerations(&self, r: &[[f64; 3]], v: &[[f64; 3]], thrust_n: &[[f64; 3]; N_MU], acc: &mut [[f64; 3]]) {
        acc.iter_mut().for_each(|a| *a = [0.0; 3]);
        self.add_edge_forces(r, v, acc);
        for (i, &c) in self.corners.iter().enumerate() {
            for ax in 0..3 {
                acc[c][ax] += thrust_n[i][ax];
            }
        }
        for i in 0..acc.len() {
            let cw = free_accel_mps2(self.n_rad_s, &r[i], &v[i]);
            for ax in 0..3 {
                acc[i][ax] = acc[i][ax] * self.inv_mass[i] + cw[ax];
            }
        }
    }

    /// Add each edge's force (N) to `force` of its two nodes.
    fn add_edge_forces(&self, r: &[[f64; 3]], v: &[[f64; 3]], force: &mut [[f64; 3]]) {
        let (rest, c) = (self.params.edge_rest_m, self.params.damping_n_s_per_m);
        let rest_sq = rest * rest;
        for &[a, b] in &self.edges {
            let d = [r[b][0] - r[a][0], r[b][1] - r[a][1], r[b][2] - r[a][2]];
            let len_sq = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
            // Slack edges (most of them while the net is folded) cost no square root.
            if len_sq < rest_sq {
                continue;
            }
            let len = len_sq.sqrt();
            let u = [d[0] / len, d[1] / len, d[2] / len];
            let rate = (v[b][0] - v[a][0]) * u[0] + (v[b][1] - v[a][1]) * u[1] + (v[b][2] - v[a][2]) * u[2];
            let f = (self.k_n_per_m * (len - rest) + c * rate).max(0.0);
            for ax in 0..3 {
                force[a][ax] += f * u[ax];
                force[b][ax] -= f * u[ax];
            }
        }
    }

    /// The net force of the edges on every node, N (written into `out`, one entry per node).
    pub fn edge_forces_n(&self, state: &NetState, out: &mut [[f64; 3]]) {
        out.iter_mut().for_each(|f| *f = [0.0; 3]);
        self.add_edge_forces(&state.r_lvlh_m, &state.v_lvlh_mps, out);
    }

    /// The tension T_i the net exerts on each MU (its corner node), N, LVLH: the "measured
    /// tension" of eq. (5).
    pub fn corner_tension_n(&self, state: &NetState) -> [[f64; 3]; N_MU] {
        let (rest, c) = (self.params.edge_rest_m, self.params.damping_n_s_per_m);
        let mut out = [[0.0; 3]; N_MU];
        for (i, &corner) in self.corners.iter().enumerate() {
            for &[a, b] in &self.edges {
                let other = if a == corner {
                    b
                } else if b == corner {
                    a
                } else {
                    continue;
                };
                let (ra, va) = (state.r_lvlh_m[corner], state.v_lvlh_mps[corner]);
                let (rb, vb) = (state.r_lvlh_m[other], state.v_lvlh_mps[other]);
                let d = [rb[0] - ra[0], rb[1] - ra[1], rb[2] - ra[2]];
                let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                if len < rest {
                    continue;
                }
                let u = [d[0] / len, d[1] / len, d[2] / len];
                let rate = (vb[0] - va[0]) * u[0] + (vb[1] - va[1]) * u[1] + (vb[2] - va[2]) * u[2];
                let f = edge_tension_n(self.params.ea_n, rest, c, len, rate);
                for ax in 0..3 {
                    out[i][ax] += f * u[ax];
                }
            }
        }
        out
    }

    /// Largest edge force in the net, N.
    pub fn max_edge_tension_n(&self, state: &NetState) -> f64 {
        let (r, v) = (&state.r_lvlh_m, &state.v_lvlh_mps);
        let mut max = 0.0f64;
        for &[a, b] in &self.edges {
            let d = [r[b][0] - r[a][0], r[b][1] - r[a][1], r[b][2] - r[a][2]];
            let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            if len < self.params.edge_rest_m {
                continue;
            }
            let u = [d[0] / len, d[1] / len, d[2] / len];
            let rate = (v[b][0] - v[a][0]) * u[0] + (v[b][1] - v[a][1]) * u[1] + (v[b][2] - v[a][2]) * u[2];
            let p = &self.params;
            max = max.max(edge_tension_n(p.ea_n, p.edge_rest_m, p.damping_n_s_per_m, len, rate));
        }
        max
    }

    /// Energy of `state` (see [`NetEnergy`]).
    pub fn energy(&self, state: &NetState) -> NetEnergy {
        let n2 = self.n_rad_s * self.n_rad_s;
        let (mut kinetic_j, mut cw_potential_j) = (0.0, 0.0);
        for ((m, r), v) in self.mass_kg.iter().zip(&state.r_lvlh_m).zip(&state.v_lvlh_mps) {
            kinetic_j += 0.5 * m * (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
            cw_potential_j += m * (-1.5 * n2 * r[0] * r[0] + 0.5 * n2 * r[2] * r[2]);
        }
        let mut elastic_j = 0.0;
        for &[a, b] in &self.edges {
            let (ra, rb) = (state.r_lvlh_m[a], state.r_lvlh_m[b]);
            let len = ((rb[0] - ra[0]).powi(2) + (rb[1] - ra[1]).powi(2) + (rb[2] - ra[2]).powi(2)).sqrt();
            let stretch = len - self.params.edge_rest_m;
            if stretch > 0.0 {
                elastic_j += 0.5 * self.k_n_per_m * stretch * stretch;
            }
        }
        NetEnergy { kinetic_j, elastic_j, cw_potential_j }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Deterministic uniform numbers in [−1, 1) (splitmix64), so the tests need no RNG crate.
    struct Uniform(u64);
    impl Uniform {
        fn next(&mut self) -> f64 {
            self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = self.0;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            z ^= z >> 31;
            (z >> 11) as f64 / (1u64 << 52) as f64 - 1.0
        }
    }

    /// A flat net in the y–z plane at x = 0, grid spacing `spacing_m`, node (row, col) at
    /// y = −col·spacing, z = −row·spacing (centred on the origin), at rest.
    fn flat(net: &Net, spacing_m: f64) -> NetState {
        let n = net.params().nodes_per_side;
        let half = 0.5 * (n - 1) as f64 * spacing_m;
        let mut s = NetState { r_lvlh_m: Vec::new(), v_lvlh_mps: vec![[0.0; 3]; n * n] };
        for row in 0..n {
            for col in 0..n {
                s.r_lvlh_m.push([0.0, half - col as f64 * spacing_m, half - row as f64 * spacing_m]);
            }
        }
        s
    }

    /// The flat net at 2 % stretch with every coordinate and velocity perturbed, so edges go
    /// slack and taut again and again.
    fn perturbed_taut(net: &Net, seed: u64) -> NetState {
        let mut s = flat(net, 0.51);
        let mut u = Uniform(seed);
        for (r, v) in s.r_lvlh_m.iter_mut().zip(&mut s.v_lvlh_mps) {
            for ax in 0..3 {
                r[ax] += 0.02 * u.next();
                v[ax] = 0.05 * u.next();
            }
        }
        s
    }

    #[test]
    fn default_net_has_the_reference_topology_and_masses() {
        let net = Net::new(NetParams::default()).unwrap();
        assert_eq!(net.n_nodes(), 121);
        assert_eq!(net.edges().len(), 220);
        assert_eq!(net.corner_nodes(), [0, 10, 110, 120]);
        let total: f64 = net.node_mass_kg().iter().sum();
        assert!((total - 41.0).abs() < 1e-12, "4 MUs of 10 kg + 1 kg of net: {total}");
        assert!((net.node_mass_kg()[1] - 1.0 / 117.0).abs() < 1e-15);
        // Each corner has exactly two edges, to the nodes next to it along the two sides.
        for c in net.corner_nodes() {
            assert_eq!(net.edges().iter().filter(|e| e.contains(&c)).count(), 2);
        }
    }

    #[test]
    fn a_single_stretched_edge_pulls_with_ea_dl_over_l() {
        // 3 × 3 net packed at 0.1 m (every edge slack), then node 0 moved so that only its edge
        // to node 1 is stretched (its edge to node 3 stays slack).
        let net = Net::new(NetParams { nodes_per_side: 3, ..NetParams::default() }).unwrap();
        let mut s = flat(&net, 0.1);
        s.r_lvlh_m[0] = [s.r_lvlh_m[3][0], s.r_lvlh_m[3][1] + 0.45, s.r_lvlh_m[3][2]];
        let d: [f64; 3] = std::array::from_fn(|ax| s.r_lvlh_m[1][ax] - s.r_lvlh_m[0][ax]);
        let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        assert!(len > 0.5 && len < 0.6, "{len}");
        let expected = 200.0 * (len - 0.5) / 0.5;
        let mut f = vec![[0.0; 3]; 9];
        net.edge_forces_n(&s, &mut f);
        for ax in 0..3 {
            let want = expected * d[ax] / len;
            assert!((f[0][ax] - want).abs() <= 1e-12 * expected, "node 0 axis {ax}: {} vs {want}", f[0][ax]);
            assert!((f[1][ax] + want).abs() <= 1e-12 * expected, "node 1 axis {ax}: {} vs {}", f[1][ax], -want);
        }
        for (i, fi) in f.iter().enumerate().skip(2) {
            assert_eq!(*fi, [0.0; 3], "node {i} has no stretched edge");
        }
        // The corner-tension function agrees (node 0 is MU 1).
        assert_eq!(net.corner_tension_n(&s)[0], f[0]);
    }

    #[test]
    fn a_slack_edge_gives_exactly_zero() {
        // Just short of the rest length, separating fast: still slack, so no damper force either.
        assert_eq!(edge_tension_n(200.0, 0.5, 0.1, 0.5 - 1e-12, 100.0), 0.0);
        // The folded net at release, moving: not one edge carries a force.
        let net = Net::new(NetParams::default()).unwrap();
        let mu_r = [[-10.0, 0.75, 0.75], [-10.0, -0.75, 0.75], [-10.0, 0.75, -0.75], [-10.0, -0.75, -0.75]];
        let mu_v = [[0.0, 1.0, 1.0], [0.0, -1.0, 1.0], [0.0, 1.0, -1.0], [0.0, -1.0, -1.0]];
        let s = net.folded_state(&mu_r, &mu_v);
        let mut f = vec![[1.0; 3]; net.n_nodes()];
        net.edge_forces_n(&s, &mut f);
        assert!(f.iter().all(|x| *x == [0.0; 3]));
        assert_eq!(net.corner_tension_n(&s), [[0.0; 3]; 4]);
        assert_eq!(net.energy(&s).elastic_j, 0.0);
    }

    #[test]
    fn the_damper_adds_while_stretching_and_the_total_is_clipped_at_zero() {
        let (ea, l, c) = (200.0, 0.5, 0.1);
        let spring = edge_tension_n(ea, l, c, 0.51, 0.0);
        assert!((spring - 4.0).abs() < 1e-12, "{spring}");
        // Separating (l̇ > 0): more pull; closing (l̇ < 0): less.
        assert!((edge_tension_n(ea, l, c, 0.51, 2.0) - (spring + 0.2)).abs() < 1e-12);
        assert!((edge_tension_n(ea, l, c, 0.51, -2.0) - (spring - 0.2)).abs() < 1e-12);
        // Closing so fast that spring + damper < 0: the tether goes limp, it does not push.
        assert_eq!(edge_tension_n(ea, l, c, 0.51, -50.0), 0.0);
        // At exactly the rest length the damper alone acts, and only while separating.
        assert!((edge_tension_n(ea, l, c, 0.5, 1.0) - 0.1).abs() < 1e-15);
        assert_eq!(edge_tension_n(ea, l, c, 0.5, -1.0), 0.0);

        // In the mesh: node 1 of a stretched edge moving away from node 0 pulls node 0 harder
        // towards it; moving towards it fast enough, not at all.
        let net = Net::new(NetParams { nodes_per_side: 3, ..NetParams::default() }).unwrap();
        let mut s = flat(&net, 0.1);
        s.r_lvlh_m[0] = [s.r_lvlh_m[3][0], s.r_lvlh_m[3][1] + 0.45, s.r_lvlh_m[3][2]];
        let force_on_0 = |s: &NetState| {
            let mut f = vec![[0.0; 3]; 9];
            net.edge_forces_n(s, &mut f);
            f[0]
        };
        let still = force_on_0(&s);
        let u: [f64; 3] = std::array::from_fn(|ax| s.r_lvlh_m[1][ax] - s.r_lvlh_m[0][ax]);
        s.v_lvlh_mps[1] = u.map(|x| 3.0 * x);
        let separating = force_on_0(&s);
        assert!(separating[1] < still[1] && still[1] < 0.0, "pulled harder in −y: {separating:?} vs {still:?}");
        s.v_lvlh_mps[1] = u.map(|x| -1e4 * x);
        assert_eq!(force_on_0(&s), [0.0; 3]);
    }

    #[test]
    fn corner_tension_is_the_edge_force_sum_and_internal_forces_cancel() {
        let net = Net::new(NetParams::default()).unwrap();
        let s = perturbed_taut(&net, 7);
        let mut f = vec![[0.0; 3]; net.n_nodes()];
        net.edge_forces_n(&s, &mut f);
        let t = net.corner_tension_n(&s);
        for (i, &c) in net.corner_nodes().iter().enumerate() {
            for ax in 0..3 {
                assert!((t[i][ax] - f[c][ax]).abs() <= 1e-12 * (1.0 + f[c][ax].abs()), "MU {}", i + 1);
            }
        }
        let pulled = t.iter().filter(|ti| ti.iter().any(|x| x.abs() > 0.1)).count();
        assert!(pulled >= 2, "the comparison needs corners under tension: {t:?}");
        for ax in 0..3 {
            let sum: f64 = f.iter().map(|x| x[ax]).sum();
            let scale: f64 = f.iter().map(|x| x[ax].abs()).sum();
            assert!(sum.abs() <= 1e-12 * scale, "axis {ax}: internal forces sum to {sum}");
        }
    }

    #[test]
    fn a_slack_net_follows_the_closed_form_cw_motion() {
        // A low orbit (n ≈ 1.1e-3 rad/s) over 300 s, nt ≈ 0.32 rad: a slip in a CW term would
        // show at the metre level. The packed net moves almost rigidly and stays slack.
        let p = NetParams { orbit_radius_m: 7_000e3, ..NetParams::default() };
        let mut net = Net::new(p.clone()).unwrap();
        let (r0, v0) = ([1.0, -2.0, 3.0], [0.01, 0.02, -0.03]);
        let mu_r = [[1.0, -2.0, 3.0], [1.0, -2.1, 3.0], [1.0, -2.0, 2.9], [1.0, -2.1, 2.9]];
        let mut s = net.folded_state(&mu_r, &[v0; 4]);
        let t = 300.0;
        for _ in 0..30 {
            net.advance(&mut s, 10.0, &[[0.0; 3]; 4]);
        }
        assert_eq!(net.energy(&s).elastic_j, 0.0, "the net stayed slack");
        let n = p.mean_motion_rad_s();
        let (sn, cn) = ((n * t).sin(), (n * t).cos());
        let [x0, y0, z0] = r0;
        let [vx, vy, vz] = v0;
        let want = [
            4.0 * x0 - 3.0 * x0 * cn + vx / n * sn + 2.0 * vy / n * (1.0 - cn),
            6.0 * x0 * (sn - n * t) + y0 - 2.0 * vx / n * (1.0 - cn) + vy / n * (4.0 * sn - 3.0 * n * t),
            z0 * cn + vz / n * sn,
        ];
        let got = s.r_lvlh_m[net.corner_nodes()[0]];
        for ax in 0..3 {
            assert!((got[ax] - want[ax]).abs() < 1e-9, "axis {ax}: {} vs {}", got[ax], want[ax]);
        }
    }

    #[test]
    fn a_free_undamped_net_conserves_its_energy() {
        // No thrust, c = 0, the CW terms on (the conserved quantity is the Jacobi integral plus
        // the elastic energy). Edges go slack and taut thousands of times; at each switch the
        // stiffness jumps and RK4 loses its order. Measured drift over these 10 s: 7.6e-3 at 1 ms,
        // 1.0e-4 at 0.2 ms, 1.9e-5 at 0.1 ms, 7.6e-6 at 0.05 ms, 1.2e-6 at 0.04 ms, 2.1e-6 at
        // 0.03 ms, 6.8e-7 at 0.02 ms (the switches make it irregular below 0.05 ms).
        let p = NetParams { damping_n_s_per_m: 0.0, substep_s: 2e-5, ..NetParams::default() };
        let mut net = Net::new(p).unwrap();
        let mut s = perturbed_taut(&net, 1);
        let e0 = net.energy(&s);
        assert!(e0.elastic_j > 0.1 && e0.kinetic_j > 1e-3, "{e0:?}");
        let mut worst = 0.0f64;
        let mut switches = 0usize;
        let edges = net.edges().to_vec();
        let taut = |s: &NetState| {
            edges
                .iter()
                .map(|&[a, b]| {
                    let (ra, rb) = (s.r_lvlh_m[a], s.r_lvlh_m[b]);
                    ((rb[0] - ra[0]).powi(2) + (rb[1] - ra[1]).powi(2) + (rb[2] - ra[2]).powi(2)) >= 0.25
                })
                .collect::<Vec<_>>()
        };
        let mut before = taut(&s);
        for _ in 0..1000 {
            net.advance(&mut s, 0.01, &[[0.0; 3]; 4]);
            let e = net.energy(&s).total_j();
            worst = worst.max((e - e0.total_j()).abs() / e0.total_j());
            let now = taut(&s);
            switches += before.iter().zip(&now).filter(|(a, b)| a != b).count();
            before = now;
        }
        assert!(switches > 1000, "the test must exercise slack/taut switching: {switches}");
        assert!(worst <= 1e-6, "relative energy drift {worst:e} over 10 s");
    }

    #[test]
    fn damping_only_removes_energy() {
        let mut net = Net::new(NetParams::default()).unwrap();
        let mut s = perturbed_taut(&net, 3);
        let mut last = net.energy(&s).total_j();
        let first = last;
        for _ in 0..200 {
            net.advance(&mut s, 0.01, &[[0.0; 3]; 4]);
            let e = net.energy(&s).total_j();
            assert!(e <= last + 1e-9 * first, "energy rose from {last} to {e}");
            last = e;
        }
        assert!(last < 0.99 * first, "the dampers dissipate: {first} → {last}");
    }

    /// Largest eigenvalue of M⁻¹K for the mesh linearised about `s` (axial stiffness k ûûᵀ plus
    /// the prestress T/l (I − ûûᵀ) of every stretched edge), by power iteration.
    fn highest_mode_rad_s(net: &Net, s: &NetState) -> f64 {
        let p = net.params();
        let k = p.stiffness_n_per_m();
        let nn = net.n_nodes();
        let apply = |x: &[[f64; 3]], y: &mut [[f64; 3]]| {
            y.iter_mut().for_each(|v| *v = [0.0; 3]);
            for &[a, b] in net.edges() {
                let d: [f64; 3] = std::array::from_fn(|ax| s.r_lvlh_m[b][ax] - s.r_lvlh_m[a][ax]);
                let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                if len < p.edge_rest_m {
                    continue;
                }
                let u = d.map(|x| x / len);
                let t_over_l = k * (len - p.edge_rest_m) / len;
                let dx: [f64; 3] = std::array::from_fn(|ax| x[a][ax] - x[b][ax]);
                let along = dx[0] * u[0] + dx[1] * u[1] + dx[2] * u[2];
                for ax in 0..3 {
                    let f = k * along * u[ax] + t_over_l * (dx[ax] - along * u[ax]);
                    y[a][ax] += f;
                    y[b][ax] -= f;
                }
            }
            for (yi, m) in y.iter_mut().zip(net.node_mass_kg()) {
                *yi = yi.map(|v| v / m);
            }
        };
        let mut u = Uniform(11);
        let mut x: Vec<[f64; 3]> = (0..nn).map(|_| [u.next(), u.next(), u.next()]).collect();
        let mut y = vec![[0.0; 3]; nn];
        let mut lambda = 0.0;
        for _ in 0..3000 {
            apply(&x, &mut y);
            let norm = y.iter().flatten().map(|v| v * v).sum::<f64>().sqrt();
            let xnorm = x.iter().flatten().map(|v| v * v).sum::<f64>().sqrt();
            lambda = norm / xnorm;
            x = y.iter().map(|v| v.map(|c| c / norm)).collect();
        }
        lambda.sqrt()
    }

    #[test]
    fn the_stability_limit_covers_the_highest_mode_of_a_taut_net() {
        let p = NetParams::default();
        let net = Net::new(p.clone()).unwrap();
        // 2 % stretch, the deployed "micro-tension" net, and 8 %.
        for spacing in [0.51, 0.54] {
            let w = highest_mode_rad_s(&net, &flat(&net, spacing));
            let chain = 2.0 * (p.stiffness_n_per_m() / p.net_node_mass_kg()).sqrt();
            assert!(w > 0.99 * chain && w <= p.highest_frequency_rad_s(), "spacing {spacing}: ω {w}, chain {chain}");
        }
        let limit = p.max_stable_substep_s();
        assert!(limit > 6e-3 && limit < 6.6e-3, "{limit}");
        assert!(p.substep_s * 6.0 < limit, "the default 1 ms keeps a margin of 6");
        let e = NetParams { substep_s: 7e-3, ..p }.validate().unwrap_err();
        assert_eq!(e.name, "substep_s");
        assert!(e.to_string().contains("stability limit"), "{e}");
    }

    #[test]
    fn bad_parameters_are_named() {
        let e = Net::new(NetParams { ea_n: f64::NAN, ..NetParams::default() }).unwrap_err();
        assert_eq!(e.name, "ea_n");
        let e = Net::new(NetParams { nodes_per_side: 2, ..NetParams::default() }).unwrap_err();
        assert_eq!(e.name, "nodes_per_side");
        let e = Net::new(NetParams { damping_n_s_per_m: -0.1, ..NetParams::default() }).unwrap_err();
        assert_eq!(e.name, "damping_n_s_per_m");
    }

    #[test]
    fn advance_splits_the_step_into_equal_substeps() {
        let p = NetParams::default();
        assert_eq!(p.substeps(0.1), 100);
        assert_eq!(p.substeps(0.1005), 101);
        assert_eq!(p.substeps(1e-4), 1);
        assert_eq!(adjacent_mus(1), [2, 3]);
        assert_eq!(adjacent_mus(4), [2, 3]);
    }
}
