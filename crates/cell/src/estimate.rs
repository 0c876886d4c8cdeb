//! The state estimate: the planner model's heat-loss coefficients fitted to the measured
//! temperatures by re-simulating what was executed.
//!
//! Two factors are fitted: `loss` scales the losses to the outside (`substrate_per_s` and
//! `radiation_per_s_k3` together) and `conduction` scales `conduction_per_s`. The objective
//! is the sum of squared differences between every measured block temperature so far and
//! the model's, re-simulated on the executed deposit sequence at the times the deposits
//! were made (a robot's dwells and moves are not the model's own time line). It is minimized by
//! coordinate-wise golden-section search on the logarithm of each factor (0.25x to 4x),
//! two sweeps: no derivatives (the simulation is a step function of thousands of Euler
//! steps), a fixed number of simulations (deterministic, about 100 per estimate, each
//! milliseconds on the sample parts), and the bracket keeps the coefficients positive.

use waam_part::graph::WeldGraph;
use waam_part::{Part, ThermalParams, Window};
use waam_thermal::{BuildState, Simulation, ThermalModel, Violation};

/// Temperatures read after the first `deposits` deposits (at the end of the last one's
/// deposit time), per welded block index, °C.
#[derive(Debug, Clone, PartialEq)]
pub struct Measurement {
    pub deposits: usize,
    pub temperatures: Vec<(usize, f64)>,
}

/// What the estimator found.
#[derive(Debug, Clone, PartialEq)]
pub struct Estimate {
    pub params: ThermalParams,
    /// Fitted factors on the nominal losses and conduction.
    pub loss: f64,
    pub conduction: f64,
    /// Root-mean-square error of the model against every measurement so far, °C: with the
    /// nominal constants and with the fitted ones.
    pub rmse_before_c: f64,
    pub rmse_after_c: f64,
    pub simulations: usize,
}

/// `part` with other thermal constants and every window widened to [0, inf): its
/// simulations run through without a violation, yet keep the t8/5 counters of the
/// windowed blocks (what [`BuildState`] carries).
pub fn counting_part(part: &Part, params: ThermalParams) -> Part {
    let mut p = part.clone();
    p.thermal = params;
    for (i, _) in part.windows().to_vec() {
        p.set_window(
            i,
            Window {
                min_s: 0.0,
                max_s: f64::INFINITY,
            },
        );
    }
    p
}

/// The constants with the two factors applied.
pub fn scaled(nominal: ThermalParams, loss: f64, conduction: f64) -> ThermalParams {
    ThermalParams {
        substrate_per_s: nominal.substrate_per_s * loss,
        radiation_per_s_k3: nominal.radiation_per_s_k3 * loss,
        conduction_per_s: nominal.conduction_per_s * conduction,
        ..nominal
    }
}

/// What was executed: each deposit as (block, begins a weld path) and when it was made,
/// (start, duration) in s on the caller's clock, which runs `clock_rate` times slower than
/// the process (a dry run's time scale).
#[derive(Debug, Clone, Copy)]
pub struct Executed<'a> {
    pub deposits: &'a [(usize, bool)],
    pub times: &'a [(f64, f64)],
    pub clock_rate: f64,
}

impl Executed<'_> {
    /// Deposits `range` made again on `sim`, each at its time (the first deposit's start at
    /// step 0; a weld path's first after the previous one's arc went out at its last
    /// deposit's end, the time between as a transit), run on to the end of the last; the
    /// first window broken on the way.
    pub fn make(
        &self,
        sim: &mut Simulation,
        range: std::ops::Range<usize>,
    ) -> Result<(), Violation> {
        let dt = sim.dt();
        let t0 = self.times.first().map_or(0.0, |t| t.0);
        let step = |t: f64| ((t - t0) * self.clock_rate / dt).round().max(0.0) as u64;
        for k in range {
            let (b, new) = self.deposits[k];
            let (start, duration) = self.times[k];
            let off = k
                .checked_sub(1)
                .map(|j| step(self.times[j].0 + self.times[j].1));
            sim.deposit_at(b, new, off, step(start))?;
            sim.run_to(step(start + duration), false)?;
        }
        Ok(())
    }
}

/// Re-simulates `executed` under `params` and returns the sum of squared errors at the
/// measurements, and their count.
fn squared_error(
    part: &Part,
    graph: &WeldGraph,
    params: ThermalParams,
    executed: Executed,
    measurements: &[Measurement],
) -> (f64, usize) {
    let p = counting_part(part, params);
    let model = ThermalModel::new(&p, graph);
    let mut sim = Simulation::new(&model).with_threads(1);
    let (mut sum, mut count, mut done) = (0.0, 0, 0);
    let mut now = vec![f64::NAN; part.len()];
    for m in measurements {
        executed
            .make(&mut sim, done..m.deposits)
            .expect("windows widened: no violation");
        done = m.deposits;
        // By block (a thermal image reads hundreds at once); the welded set only grows.
        for (b, t) in sim.temperatures() {
            now[b] = t;
        }
        for &(b, measured) in &m.temperatures {
            if let Some(&t) = now.get(b).filter(|t| !t.is_nan()) {
                sum += (t - measured).powi(2);
                count += 1;
            }
        }
    }
    (sum, count)
}

/// Fits the loss and conduction factors of `nominal` to `measurements` of `executed`.
pub fn fit(
    part: &Part,
    nominal: ThermalParams,
    executed: Executed,
    measurements: &[Measurement],
) -> Estimate {
    let graph = WeldGraph::new(part);
    let mut simulations = 0;
    let mut cost = |loss: f64, conduction: f64| {
        simulations += 1;
        squared_error(
            part,
            &graph,
            scaled(nominal, loss, conduction),
            executed,
            measurements,
        )
    };
    let (before, count) = cost(1.0, 1.0);
    let rms = |sum: f64| (sum / count.max(1) as f64).sqrt();
    if count == 0 {
        // Nothing measured: every factor fits equally; the model stays nominal.
        return Estimate {
            params: nominal,
            loss: 1.0,
            conduction: 1.0,
            rmse_before_c: 0.0,
            rmse_after_c: 0.0,
            simulations,
        };
    }
    let (mut loss, mut conduction) = (1.0f64, 1.0f64);
    for _sweep in 0..2 {
        loss = golden(|x| cost(x.exp(), conduction).0).exp();
        conduction = golden(|x| cost(loss, x.exp()).0).exp();
    }
    let (after, _) = cost(loss, conduction);
    // Never worse than the nominal model (golden section finds a local minimum).
    let (loss, conduction, after) = if after <= before {
        (loss, conduction, after)
    } else {
        (1.0, 1.0, before)
    };
    Estimate {
        params: scaled(nominal, loss, conduction),
        loss,
        conduction,
        rmse_before_c: rms(before),
        rmse_after_c: rms(after),
        simulations,
    }
}

/// The minimum of `f` on [ln 1/4, ln 4] by golden-section search, 24 iterations (the
/// bracket shrinks to 1e-5 of its width).
fn golden(mut f: impl FnMut(f64) -> f64) -> f64 {
    let r = (5f64.sqrt() - 1.0) / 2.0;
    let (mut a, mut b) = (-(4f64.ln()), 4f64.ln());
    let mut c = b - r * (b - a);
    let mut d = a + r * (b - a);
    let (mut fc, mut fd) = (f(c), f(d));
    for _ in 0..24 {
        if fc <= fd {
            b = d;
            d = c;
            fd = fc;
            c = b - r * (b - a);
            fc = f(c);
        } else {
            a = c;
            c = d;
            fc = fd;
            d = a + r * (b - a);
            fd = f(d);
        }
    }
    (a + b) / 2.0
}

/// The estimated state after `executed` under `params`, at the end of its last deposit:
/// what [`waam_planner::plan_rest`] starts from.
pub fn state(part: &Part, params: ThermalParams, executed: Executed) -> BuildState {
    let p = counting_part(part, params);
    let graph = WeldGraph::new(&p);
    let model = ThermalModel::new(&p, &graph);
    let mut sim = Simulation::new(&model).with_threads(1);
    executed
        .make(&mut sim, 0..executed.deposits.len())
        .expect("windows widened: no violation");
    sim.state()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_fit_recovers_lower_losses_from_exact_measurements() {
        let part = Part::parse(
            "name: w\nblock_mm: [6,6,2.5]\nmax_fragments: 1\nlayers: ['####', '####', '####']\n",
        )
        .unwrap();
        let order: Vec<(usize, bool)> = [0, 1, 2, 3, 7, 6, 5, 4, 8, 9, 10, 11]
            .iter()
            .enumerate()
            .map(|(p, &b)| (b, p == 0))
            .collect();
        let truth = scaled(part.thermal, 0.75, 1.0);
        // One weld path: a deposit a second (`block_time_s` 1), from 100 s on the caller's
        // clock.
        let times: Vec<(f64, f64)> = (0..order.len()).map(|k| (100.0 + k as f64, 1.0)).collect();
        let executed = |d: usize| Executed {
            deposits: &order[..d],
            times: &times[..d],
            clock_rate: 1.0,
        };
        let measurements: Vec<Measurement> = [4, 8, 12]
            .iter()
            .map(|&d| {
                let s = state(&part, truth, executed(d));
                Measurement {
                    deposits: d,
                    temperatures: s.order.iter().map(|o| o.0).zip(s.temperatures).collect(),
                }
            })
            .collect();
        let e = fit(&part, part.thermal, executed(12), &measurements);
        assert!((e.loss - 0.75).abs() < 0.01, "{e:?}");
        assert!((e.conduction - 1.0).abs() < 0.05, "{e:?}");
        assert!(e.rmse_before_c > 10.0 && e.rmse_after_c < 1.0, "{e:?}");
        // Nothing measured: the nominal model (a flat objective once drove it to 1/4).
        let none = fit(&part, part.thermal, executed(12), &[]);
        assert_eq!((none.loss, none.conduction), (1.0, 1.0));
        assert_eq!(none.params, part.thermal);
    }
}
