//! The bit-identity test: the fast step (slots, SIMD, threads) against a plain scalar
//! reference of the spec's step on random parts, plans and constants.

use proptest::prelude::*;
use waam_part::graph::{WeldGraph, NONE};
use waam_part::{Part, ThermalParams};

use super::Simd;
use crate::model::ThermalModel;
use crate::simulation::Simulation;

/// The spec's step written plainly: one temperature per block, a neighbour that is
/// absent or not welded read as T_i, the fluxes summed in face order (-x, +x, -y, +y,
/// -z, +z), then the substrate term, then radiation (r · e_i) · ((T+273.15)²)² − q).
struct Reference<'m> {
    m: &'m ThermalModel,
    temp: Vec<f64>,
    welded: Vec<bool>,
    fragments: usize,
    steps: u64,
}

impl<'m> Reference<'m> {
    fn new(m: &'m ThermalModel) -> Self {
        Reference {
            m,
            temp: vec![0.0; m.len()],
            welded: vec![false; m.len()],
            fragments: 0,
            steps: 0,
        }
    }

    fn step(&mut self) {
        let p = &self.m.params;
        let (h, amb, q, dt) = (
            p.conduction_per_s,
            p.ambient_c,
            self.m.ambient_k4,
            self.m.dt,
        );
        let old = self.temp.clone();
        for i in (0..old.len()).filter(|&i| self.welded[i]) {
            let ti = old[i];
            let faces = self.m.faces[i];
            let on = |k: usize| faces[k] != NONE && self.welded[faces[k] as usize];
            let t = |k: usize| if on(k) { old[faces[k] as usize] } else { ti };
            let mut f = h * (t(0) - ti);
            for k in 1..6 {
                f += h * (t(k) - ti);
            }
            let z0 = self.m.on_substrate[i];
            let hs = if z0 { p.substrate_per_s } else { 0.0 };
            f += hs * (amb - ti);
            let e = 6 - (0..6).filter(|&k| on(k)).count() as u8 - z0 as u8;
            let tk = ti + 273.15;
            let t2 = tk * tk;
            f -= (p.radiation_per_s_k3 * e as f64) * (t2 * t2 - q);
            self.temp[i] = ti + dt * f;
        }
        self.steps += 1;
    }

    fn deposit(&mut self, b: usize, new_fragment: bool) {
        if new_fragment && self.fragments > 0 {
            for _ in 0..self.m.transit_steps {
                self.step();
            }
        }
        self.fragments += new_fragment as usize;
        self.welded[b] = true;
        self.temp[b] = self.m.params.deposit_c;
        for _ in 0..self.m.params.substeps {
            self.step();
        }
    }

    /// (block, temperature bits) of the welded blocks, by block.
    fn state(&self) -> Vec<(usize, u64)> {
        (0..self.temp.len())
            .filter(|&i| self.welded[i])
            .map(|i| (i, self.temp[i].to_bits()))
            .collect()
    }
}

fn state(sim: &Simulation<'_>) -> Vec<(usize, u64)> {
    let mut v: Vec<_> = sim.temperatures().map(|(b, t)| (b, t.to_bits())).collect();
    v.sort_unstable();
    v
}

prop_compose! {
    fn case()(
        dims in (1i64..7, 1i64..6, 1i64..6),
        fill in proptest::collection::vec(any::<u8>(), 6 * 5 * 5),
        density in 96u8..=255,
        seed in any::<u64>(),
        news in proptest::collection::vec(any::<u8>(), 150),
        h in 0.0f64..3.0,
        hs in 0.0f64..3.0,
        r in 0.0f64..5e-12,
        ambient in -30.0f64..120.0,
        deposit in 300.0f64..3000.0,
        substeps in 1u32..25,
        block_time in 0.2f64..2.0,
        transit in 0.0f64..6.0,
    ) -> (Part, Vec<(usize, bool)>) {
        let (nx, ny, nz) = dims;
        let mut blocks = Vec::new();
        for z in 0..nz {
            for y in 0..ny {
                for x in 0..nx {
                    if fill[(z * 30 + y * 6 + x) as usize] <= density {
                        blocks.push([x, y, z]);
                    }
                }
            }
        }
        if blocks.is_empty() {
            blocks.push([0, 0, 0]);
        }
        let mut part = Part::from_blocks("p".into(), [6.0, 6.0, 2.5], [0.0; 3], 3, blocks)
            .expect("a generated part");
        part.thermal = ThermalParams {
            ambient_c: ambient,
            deposit_c: deposit,
            block_time_s: block_time,
            substeps,
            transit_time_s: transit,
            conduction_per_s: h,
            substrate_per_s: hs,
            radiation_per_s_k3: r,
            max_cooldown_s: 0.0,
        };
        // A random deposit order (any order: the simulator does not check plans).
        let mut order: Vec<usize> = (0..part.len()).collect();
        let mut x = seed | 1;
        for i in (1..order.len()).rev() {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            order.swap(i, (x % (i as u64 + 1)) as usize);
        }
        let seq = order
            .into_iter()
            .enumerate()
            .map(|(p, b)| (b, p == 0 || news[p] < 40))
            .collect();
        (part, seq)
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]
    #[test]
    fn fast_step_is_bit_identical_to_the_reference((part, seq) in case()) {
        let graph = WeldGraph::new(&part);
        let model = ThermalModel::new(&part, &graph);
        let kernels: Vec<ThermalModel> =
            Simd::available().into_iter().map(|s| model.clone().with_simd(s)).collect();
        let mut reference = Reference::new(&model);
        let mut sims: Vec<Simulation<'_>> = kernels
            .iter()
            .map(|m| Simulation::new(m).with_threads(1))
            .collect();
        sims.push(Simulation::new(&model).with_threads(2).with_parallel_min(0));
        let mut snaps = Vec::new();
        for &(b, new) in &seq {
            reference.deposit(b, new);
            let want = reference.state();
            for sim in &mut sims {
                sim.deposit(b, new).unwrap();
                prop_assert_eq!(sim.steps(), reference.steps);
                prop_assert_eq!(&state(sim), &want);
            }
            snaps.push((sims[0].snapshot(), want));
        }
        // Back to a random earlier prefix and forward again: the same bits.
        let back = seq.len() / 2;
        let (snap, want) = &snaps[back];
        for sim in &mut sims {
            sim.restore(snap);
            prop_assert_eq!(&state(sim), want);
        }
        let mut fresh = Simulation::new(&model);
        fresh.restore_from_trail(snap, &seq);
        prop_assert_eq!(&state(&fresh), want);
        for &(b, new) in &seq[back + 1..] {
            fresh.deposit(b, new).unwrap();
        }
        prop_assert_eq!(state(&fresh), reference.state());
    }
}

/// The radiation term is ((T + 273.15)²)², not powi(4) or powf(4): the same bits as
/// the simulator has always computed (and powf only for the ambient constant).
#[test]
fn radiation_is_the_square_of_the_square() {
    for t in [20.0f64, 500.0, 800.0, 2500.0, 1234.5678] {
        let tk = t + 273.15;
        let t2 = tk * tk;
        assert_eq!((t2 * t2).to_bits(), (tk * tk * (tk * tk)).to_bits());
    }
}
