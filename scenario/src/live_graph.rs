//! The conditions a formation needs of its graph, evaluated on any subset of live agents: the
//! scenario check uses them on the full roster, the orchestrator again whenever the roster
//! changes (a dead agent can disconnect the survivors, or take away the only measurement of an
//! axis of the defunct spacecraft).

use crate::schema::AgentConfig;

/// Connected components of the undirected communication graph restricted to the agents with
/// `live[id − 1]`, each as ascending ids, ordered by their smallest id. Ids must be 1..=N.
pub fn components(agents: &[AgentConfig], live: &[bool]) -> Vec<Vec<u32>> {
    let n = agents.len();
    let on = |id: usize| live.get(id - 1).copied().unwrap_or(false);
    let mut adj = vec![Vec::new(); n + 1];
    for a in agents.iter().filter(|a| on(a.id as usize)) {
        for &j in a.neighbours.iter().filter(|&&j| (j as usize) <= n && on(j as usize)) {
            adj[a.id as usize].push(j as usize);
            adj[j as usize].push(a.id as usize);
        }
    }
    let mut comp = vec![0usize; n + 1];
    let mut groups = Vec::new();
    for start in (1..=n).filter(|&v| on(v)) {
        if comp[start] != 0 {
            continue;
        }
        groups.push(Vec::new());
        let g = groups.len();
        let mut stack = vec![start];
        comp[start] = g;
        while let Some(v) = stack.pop() {
            groups[g - 1].push(v as u32);
            for &w in &adj[v] {
                if comp[w] == 0 {
                    comp[w] = g;
                    stack.push(w);
                }
            }
        }
    }
    for g in &mut groups {
        g.sort_unstable();
    }
    groups
}

/// rank(Σ bᵢ CᵢᵀCᵢ) over the live agents (Def. 1 of seed 000) and its eigenvalues, when every
/// agent has an output matrix (the seed-000 scenarios); None otherwise.
pub fn trackability(agents: &[AgentConfig], live: &[bool]) -> Option<(usize, [f64; 3])> {
    if agents.is_empty() || !agents.iter().all(|a| a.output_matrix.is_some()) {
        return None;
    }
    let mut sum = nalgebra::Matrix3::<f64>::zeros();
    for a in agents.iter().filter(|a| a.b() == 1 && live.get(a.id as usize - 1).copied().unwrap_or(false)) {
        for row in a.output_matrix.as_ref().expect("checked above") {
            let v = nalgebra::Vector3::from_row_slice(row);
            sum += v * v.transpose();
        }
    }
    let eig = sum.symmetric_eigenvalues();
    let max = eig.iter().cloned().fold(0.0, f64::max);
    let rank = eig.iter().filter(|&&e| e > 1e-9 * max.max(1e-300)).count();
    Some((rank, [eig[0], eig[1], eig[2]]))
}

/// What no longer holds with only the `live` agents, in words (empty: all is well).
pub fn warnings(agents: &[AgentConfig], live: &[bool]) -> Vec<String> {
    let mut out = Vec::new();
    let groups = components(agents, live);
    if groups.len() > 1 {
        let g: Vec<String> = groups
            .iter()
            .map(|g| format!("{{{}}}", g.iter().map(|v| v.to_string()).collect::<Vec<_>>().join(", ")))
            .collect();
        out.push(format!("the live communication graph is disconnected: {}", g.join(" and ")));
    }
    if let Some((rank, _)) = trackability(agents, live)
        && rank < 3
    {
        out.push(format!(
            "the defunct spacecraft is no longer trackable by the live servicers (Def. 1 of seed 000): \
             rank(Σ bᵢ CᵢᵀCᵢ) = {rank} < 3"
        ));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fig1() -> Vec<AgentConfig> {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../topologies/fig1.toml");
        crate::load(&path, &Default::default()).unwrap().agents
    }

    #[test]
    fn fig1_ring_survives_one_loss_but_not_two_opposite_ones() {
        let a = fig1();
        assert!(warnings(&a, &[true; 6]).is_empty());
        assert!(warnings(&a, &[true, true, false, true, true, true]).is_empty(), "a ring minus one is a path");
        let w = warnings(&a, &[true, true, false, true, true, false]);
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(w[0].contains("{1, 2} and {4, 5}"), "{w:?}");
    }

    #[test]
    fn trackability_is_lost_when_the_full_rank_servicers_die() {
        let a = fig1();
        assert_eq!(trackability(&a, &[true; 6]).unwrap().0, 3);
        // Servicers 4 and 5 carry three rows each; the others one or two.
        let w = warnings(&a, &[true, false, false, false, false, true]);
        assert!(w.iter().any(|m| m.contains("no longer trackable")), "{w:?}");
    }
}
