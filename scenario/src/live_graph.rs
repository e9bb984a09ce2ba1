//! The conditions a formation needs of its graph, evaluated on any subset of live agents: the
//! scenario check uses them on the full roster, the orchestrator again whenever the roster
//! changes (a dead agent can disconnect the survivors).

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

/// What no longer holds of the graph with only the `live` agents, in words (empty: all is well).
/// A plant adds what its paper needs of the live set (see the runtime's `PlantSetup`).
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
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ring(n: u32) -> Vec<AgentConfig> {
        (1..=n)
            .map(|i| AgentConfig {
                id: i,
                neighbours: vec![if i == 1 { n } else { i - 1 }, if i == n { 1 } else { i + 1 }],
                host: None,
                extra: toml::Table::new(),
            })
            .collect()
    }

    #[test]
    fn a_ring_survives_one_loss_but_not_two_opposite_ones() {
        let a = ring(6);
        assert!(warnings(&a, &[true; 6]).is_empty());
        assert!(warnings(&a, &[true, true, false, true, true, true]).is_empty(), "a ring minus one is a path");
        let w = warnings(&a, &[true, true, false, true, true, false]);
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(w[0].contains("{1, 2} and {4, 5}"), "{w:?}");
    }
}
