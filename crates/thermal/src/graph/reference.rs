//! The doc's step written plainly: the yardstick the fast step is tested against, and the
//! code another program can read next to `docs/graph-thermal-model.md`.

use super::GraphModel;

/// A plain simulation of the graph model: one temperature per node, only welded nodes
/// stepped, everything recomputed from the welded set every step.
#[derive(Debug, Clone)]
pub struct GraphReference<'m> {
    model: &'m GraphModel,
    temp: Vec<f64>,
    welded: Vec<bool>,
    steps: u64,
}

impl<'m> GraphReference<'m> {
    /// Every node unwelded at ambient.
    pub fn new(model: &'m GraphModel) -> Self {
        GraphReference {
            model,
            temp: vec![model.params.ambient_c; model.len()],
            welded: vec![false; model.len()],
            steps: 0,
        }
    }

    /// Deposits `node`: T = deposit_c, welded from now on (no steps).
    ///
    /// # Panics
    /// If `node` is already welded.
    pub fn deposit(&mut self, node: usize) {
        assert!(!self.welded[node], "node {node} deposited twice");
        self.welded[node] = true;
        self.temp[node] = self.model.params.deposit_c;
    }

    /// One Euler step of every welded node, all fluxes from the temperatures before it.
    pub fn step(&mut self) {
        let m = self.model;
        let p = &m.params;
        let old = self.temp.clone();
        let welded = |j: u32| self.welded[j as usize];
        for i in (0..old.len()).filter(|&i| self.welded[i]) {
            let ti = old[i];
            let mut f = 0.0;
            for l in m.links(i) {
                if welded(l.other) {
                    f += l.coef * (old[l.other as usize] - ti);
                }
            }
            f += m.substrate[i] * (p.ambient_c - ti);
            let tk = ti + 273.15;
            let t2 = tk * tk;
            f -= m.radiation(i, welded) * (t2 * t2 - m.ambient_k4);
            self.temp[i] = ti + m.dt * f;
        }
        self.steps += 1;
    }

    /// `n` steps.
    pub fn run(&mut self, n: u64) {
        for _ in 0..n {
            self.step();
        }
    }

    /// Temperatures by node, °C (unwelded nodes at ambient).
    pub fn temperatures(&self) -> &[f64] {
        &self.temp
    }

    /// Whether `node` is welded.
    pub fn is_welded(&self, node: usize) -> bool {
        self.welded[node]
    }

    /// Steps done so far.
    pub fn steps(&self) -> u64 {
        self.steps
    }
}
