//! The 3-D scene (`/scene`, `foxglove.SceneUpdate`): each body of the paper's declaration
//! (`RunHooks::scene`) as a sphere at its truth and, where its algorithm estimates a position, a
//! translucent ghost there; the communication graph as lines between the agents' truths, coloured
//! by the link's state at that step.

use std::collections::BTreeSet;

use cohort_host::{SceneBody, ScenePosition};
use cohort_runtime::paper::Setup;
use foxglove::messages::{
    Color, LinePrimitive, Pose, Quaternion, SceneEntity, SceneUpdate, SpherePrimitive, TextPrimitive, Timestamp,
    Vector3, line_primitive,
};

/// The scene's one frame (the paper's position columns are all in one frame).
pub const FRAME: &str = "formation";

/// A link's state, as its line's colour shows it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Link {
    Alive,
    Delayed,
    Dropped,
    /// One end is off the roster.
    DeadNeighbour,
}

impl Link {
    pub fn name(self) -> &'static str {
        match self {
            Link::Alive => "alive",
            Link::Delayed => "delayed",
            Link::Dropped => "dropped",
            Link::DeadNeighbour => "dead neighbour",
        }
    }
    fn color(self) -> Color {
        match self {
            Link::Alive => rgba(0.2, 0.8, 0.3, 1.0),
            Link::Delayed => rgba(1.0, 0.65, 0.0, 1.0),
            Link::Dropped => rgba(0.9, 0.1, 0.1, 1.0),
            Link::DeadNeighbour => rgba(0.5, 0.5, 0.5, 0.6),
        }
    }
}

fn rgba(r: f64, g: f64, b: f64, a: f64) -> Color {
    Color { r, g, b, a }
}

/// The state of the link that carries `from`'s shares to `to` at sim time `t_s`: a dead end wins,
/// then a drop or corrupt fault of the sender, then a delay fault.
pub fn link_state(setup: &Setup, dead: &BTreeSet<u32>, from: u32, to: u32, t_s: f64) -> Link {
    if dead.contains(&from) || dead.contains(&to) {
        return Link::DeadNeighbour;
    }
    let active = |kinds: &[&str]| {
        setup.faults.iter().any(|f| {
            f.agent == from
                && kinds.contains(&f.kind.as_str())
                && f.t_s <= t_s
                && f.for_s.is_none_or(|d| t_s < f.t_s + d)
        })
    };
    if active(&["drop", "corrupt"]) {
        Link::Dropped
    } else if active(&["delay"]) {
        Link::Delayed
    } else {
        Link::Alive
    }
}

/// A position from the latest rows: `row(process)` gives that process's columns and values.
pub fn position<'a>(p: &ScenePosition, row: &impl Fn(&str) -> Option<(&'a [String], &'a [f64])>) -> Option<[f64; 3]> {
    let (columns, values) = row(&p.process)?;
    // Values follow `k`: column c is value c − 1.
    let at =
        |name: &String| columns.iter().position(|c| c == name).and_then(|c| values.get(c.checked_sub(1)?)).copied();
    Some([at(&p.columns[0])?, at(&p.columns[1])?, at(&p.columns[2])?])
}

/// What one scene shows, positions already read.
pub struct Frame<'a> {
    pub t_ns: u64,
    pub bodies: &'a [SceneBody],
    pub truth: Vec<Option<[f64; 3]>>,
    pub estimate: Vec<Option<[f64; 3]>>,
    /// (from, to, state) of every link of the graph.
    pub links: Vec<(u32, u32, Link)>,
    pub dead: &'a BTreeSet<u32>,
}

fn v3(p: [f64; 3]) -> Vector3 {
    Vector3 { x: p[0], y: p[1], z: p[2] }
}

fn pose(p: [f64; 3]) -> Pose {
    Pose { position: Some(v3(p)), orientation: Some(Quaternion { x: 0.0, y: 0.0, z: 0.0, w: 1.0 }) }
}

fn sphere(p: [f64; 3], size_m: f64, color: Color) -> SpherePrimitive {
    SpherePrimitive { pose: Some(pose(p)), size: Some(v3([size_m; 3])), color: Some(color) }
}

fn entity(id: String, t: Timestamp) -> SceneEntity {
    SceneEntity { timestamp: Some(t), frame_id: FRAME.into(), id, ..Default::default() }
}

/// The scene update of one frame. Sphere sizes follow the formation's extent (2 % of it), so a
/// formation of kilometres and one of metres both show.
pub fn update(f: &Frame<'_>) -> SceneUpdate {
    let t = Timestamp::new((f.t_ns / 1_000_000_000) as u32, (f.t_ns % 1_000_000_000) as u32);
    let known: Vec<[f64; 3]> = f.truth.iter().flatten().copied().collect();
    let extent = (0..3)
        .map(|a| {
            let (lo, hi) =
                known.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), p| (l.min(p[a]), h.max(p[a])));
            hi - lo
        })
        .fold(0.0, f64::max);
    let size = if extent.is_finite() && extent > 0.0 { 0.02 * extent } else { 1.0 };
    let mut entities = Vec::new();
    for (b, body) in f.bodies.iter().enumerate() {
        let mut e = entity(body.name.clone(), t);
        let dead = body.agent.is_some_and(|a| f.dead.contains(&a));
        if let Some(p) = f.truth[b] {
            let color = if dead {
                rgba(0.5, 0.5, 0.5, 1.0)
            } else if body.agent.is_some() {
                rgba(0.2, 0.5, 1.0, 1.0)
            } else {
                rgba(1.0, 0.85, 0.2, 1.0)
            };
            e.spheres.push(sphere(p, size, color));
            e.texts.push(TextPrimitive {
                pose: Some(pose([p[0], p[1], p[2] + size])),
                billboard: true,
                font_size: 14.0,
                scale_invariant: true,
                color: Some(rgba(1.0, 1.0, 1.0, 1.0)),
                text: body.name.clone(),
            });
        }
        if let Some(p) = f.estimate[b] {
            e.spheres.push(sphere(p, 0.6 * size, rgba(0.2, 0.5, 1.0, 0.35)));
        }
        entities.push(e);
    }
    entities.push(graph(f, t, size));
    SceneUpdate { deletions: Vec::new(), entities }
}

/// The communication graph: one line per link between the truths of its two agents.
fn graph(f: &Frame<'_>, t: Timestamp, size: f64) -> SceneEntity {
    let of_agent = |a: u32| f.bodies.iter().position(|b| b.agent == Some(a)).and_then(|b| f.truth[b]);
    let mut e = entity("links".into(), t);
    let (mut points, mut colors) = (Vec::new(), Vec::new());
    for &(from, to, state) in &f.links {
        let (Some(p), Some(q)) = (of_agent(from), of_agent(to)) else { continue };
        for r in [p, q] {
            points.push(foxglove::messages::Point3 { x: r[0], y: r[1], z: r[2] });
            colors.push(state.color());
        }
        e.metadata.push(foxglove::messages::KeyValuePair {
            key: format!("agent-{from}->agent-{to}"),
            value: state.name().into(),
        });
    }
    e.lines.push(LinePrimitive {
        r#type: line_primitive::Type::LineList as i32,
        pose: Some(pose([0.0; 3])),
        thickness: 0.15 * size,
        scale_invariant: false,
        points,
        color: Some(Link::Alive.color()),
        colors,
        indices: Vec::new(),
    });
    e
}
