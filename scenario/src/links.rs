//! `[links]`: how the inter-satellite links between neighbours behave. `ideal` (the default):
//! every share reaches its readers in the step it was sent. `geometric`: the plant decides, from
//! the true positions at each step, whether each directed link is in view, how many whole steps a
//! share takes (light time, processing, the time its bits take at the link's data rate), whether
//! it is lost (a constant rate, a range table, or a link budget), and whether the link is still
//! busy with the previous share (the rate cap). The plant's model (runtime `links`) applies it.

use serde::{Deserialize, Serialize};

use crate::checker::{Checker, fmt_f64};

/// Speed of light in vacuum, m/s.
pub const C_MPS: f64 = 299_792_458.0;
/// Most steps a share may take on a link (a longer one is refused when the scenario is checked:
/// it would outlive every use).
pub const MAX_LINK_DELAY_STEPS: u64 = 60_000;

#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum LinkKind {
    #[default]
    Ideal,
    Geometric,
}

/// `[links]` as written.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Links {
    #[serde(default)]
    pub model: LinkKind,
    /// Carrier acquisition, coding and on-board handling added to the light time, s.
    #[serde(default)]
    pub processing_latency_s: f64,
    /// Beyond this range, m, a link is down (the receiver cannot close it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_range_m: Option<f64>,
    /// Radius of the occulting body centred on the plant's frame origin, m (the Earth's
    /// equatorial radius plus an atmosphere margin for grazing rays); absent: nothing occults.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub occulting_radius_m: Option<f64>,
    /// Per-link data rate, bit/s: a share takes its size over this rate to send, and a link still
    /// sending the previous share drops the new one (absent: no cap, no serialisation time).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub data_rate_bps: Option<f64>,
    /// How often a share in view is lost.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub loss: Option<Loss>,
}

/// The loss law of `[links.loss]`, by `law`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "law", rename_all = "lowercase", deny_unknown_fields)]
pub enum Loss {
    /// The same probability on every link and step.
    Constant { p: f64 },
    /// Loss probability by range, linear between the points, held beyond the ends.
    Table { range_m: Vec<f64>, p: Vec<f64> },
    /// A link budget: received power from the Friis equation, Eb/N0 at the data rate, the bit
    /// error rate of BPSK with the coding gain that makes `required_ebn0_db` give a bit error rate
    /// of 1e-5, and a share lost when any of its bits is wrong.
    Budget {
        tx_power_w: f64,
        tx_gain_dbi: f64,
        rx_gain_dbi: f64,
        frequency_hz: f64,
        noise_temperature_k: f64,
        /// The Eb/N0 the modem and code need for a bit error rate of 1e-5, dB (the budget is
        /// closed at `links.data_rate_bps`).
        required_ebn0_db: f64,
    },
}

impl Links {
    pub fn is_geometric(&self) -> bool {
        self.model == LinkKind::Geometric
    }
}

/// The checks of `[links]`: every number finite and in range, a table sorted, and no key that
/// means something only to the geometric model set under `ideal`.
pub fn check(c: &mut Checker, l: &Links, dt_s: f64) {
    if !l.is_geometric() {
        let set = [
            ("processing_latency_s", l.processing_latency_s != 0.0),
            ("max_range_m", l.max_range_m.is_some()),
            ("occulting_radius_m", l.occulting_radius_m.is_some()),
            ("data_rate_bps", l.data_rate_bps.is_some()),
            ("loss", l.loss.is_some()),
        ];
        for (key, _) in set.iter().filter(|(_, on)| *on) {
            c.fail(format!("links.{key}"), "(set)", "applies to model = \"geometric\" only (links.model is \"ideal\")");
        }
        return;
    }
    c.non_negative("links.processing_latency_s", l.processing_latency_s);
    if let Some(r) = l.max_range_m {
        c.positive("links.max_range_m", r);
    }
    if let Some(r) = l.occulting_radius_m {
        c.positive("links.occulting_radius_m", r);
    }
    if let Some(r) = l.data_rate_bps {
        c.positive("links.data_rate_bps", r);
    }
    if let Some(loss) = &l.loss {
        check_loss(c, loss);
        if matches!(loss, Loss::Budget { .. }) && l.data_rate_bps.is_none() {
            c.missing("links.data_rate_bps", "required by links.loss.law = \"budget\" (Eb/N0 is energy per bit)");
        }
    }
    let longest = l.max_range_m.map(|r| r / C_MPS + l.processing_latency_s);
    if let Some(s) = longest.filter(|s| s.is_finite() && dt_s > 0.0 && (s / dt_s).ceil() > MAX_LINK_DELAY_STEPS as f64)
    {
        c.fail(
            "links.max_range_m",
            fmt_f64(l.max_range_m.unwrap_or_default()),
            format!("a share would take {s:.3} s, more than {MAX_LINK_DELAY_STEPS} steps of {dt_s} s"),
        );
    }
}

fn check_loss(c: &mut Checker, loss: &Loss) {
    let probability = |c: &mut Checker, path: &str, p: f64| {
        if c.finite(path, p) && !(0.0..=1.0).contains(&p) {
            c.fail(path, fmt_f64(p), "a probability must be in [0, 1]");
        }
    };
    match loss {
        Loss::Constant { p } => probability(c, "links.loss.p", *p),
        Loss::Table { range_m, p } => {
            if range_m.is_empty() || range_m.len() != p.len() {
                let why = format!("needs as many entries as links.loss.p ({}), at least one", p.len());
                c.fail("links.loss.range_m", format!("{} entries", range_m.len()), why);
            }
            for (i, r) in range_m.iter().enumerate() {
                c.non_negative(&format!("links.loss.range_m[{i}]"), *r);
                if i > 0 && *r <= range_m[i - 1] {
                    c.fail(format!("links.loss.range_m[{i}]"), fmt_f64(*r), "ranges must increase");
                }
            }
            for (i, x) in p.iter().enumerate() {
                probability(c, &format!("links.loss.p[{i}]"), *x);
            }
        }
        Loss::Budget { tx_power_w, tx_gain_dbi, rx_gain_dbi, frequency_hz, noise_temperature_k, required_ebn0_db } => {
            c.positive("links.loss.tx_power_w", *tx_power_w);
            c.finite("links.loss.tx_gain_dbi", *tx_gain_dbi);
            c.finite("links.loss.rx_gain_dbi", *rx_gain_dbi);
            c.positive("links.loss.frequency_hz", *frequency_hz);
            c.positive("links.loss.noise_temperature_k", *noise_temperature_k);
            c.finite("links.loss.required_ebn0_db", *required_ebn0_db);
        }
    }
}
