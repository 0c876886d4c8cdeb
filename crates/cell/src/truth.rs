//! TRUTH.yaml: how the simulated cell differs from the planner's model (docs/closed-loop.md).

use serde_yaml::{Mapping, Value};
use thiserror::Error;

use waam_part::{Part, ThermalParams};

/// A TRUTH.yaml that cannot be used (the message names the key and what is wrong).
#[derive(Debug, Clone, PartialEq, Error)]
#[error("TRUTH.yaml: {0}")]
pub struct TruthError(pub String);

/// A weld path stopped early (a wire fault): weld path `path` (1 = the first begun) stops
/// after `after` deposits.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CutShort {
    pub path: usize,
    pub after: usize,
}

/// A box of the part frame (mm, bounds inclusive) whose deposits come out `factor` times
/// the height asked for.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HeightZone {
    pub min_mm: [f64; 3],
    pub max_mm: [f64; 3],
    pub factor: f64,
}

/// The true cell.
#[derive(Debug, Clone, PartialEq)]
pub struct Truth {
    /// The part's thermal constants with TRUTH.yaml's `thermal:` keys over them.
    pub thermal: ThermalParams,
    /// Deposit height / the height the wire feed asks for (0.9: every deposit 10 % low).
    pub height_factor: f64,
    /// Regions of the part with their own height factor (a cold fixture, a worn liner): a
    /// deposit whose centre lies in one takes its factor (the last zone listed wins).
    pub height_zones: Vec<HeightZone>,
    pub cut_short: Vec<CutShort>,
    /// Standard deviation of the temperature sensor's noise, °C (0: exact), and its seed.
    pub noise_c: f64,
    pub seed: u64,
}

const KEYS: [&str; 5] = [
    "thermal",
    "height_factor",
    "height_zones",
    "cut_short",
    "sensors",
];

impl Truth {
    /// Reads TRUTH.yaml for `part`: every key optional (an empty file is the planner's own
    /// model, heights as asked, no faults, exact sensors).
    pub fn parse(text: &str, part: &Part) -> Result<Truth, TruthError> {
        let bad = |m: String| TruthError(m);
        let doc: Value = serde_yaml::from_str(text).map_err(|e| bad(e.to_string()))?;
        let map = match doc {
            Value::Null => Mapping::new(),
            Value::Mapping(m) => m,
            _ => return Err(bad("expected a mapping of keys".into())),
        };
        for key in map.keys() {
            let name = key.as_str().unwrap_or("");
            if !KEYS.contains(&name) {
                return Err(bad(format!(
                    "unknown key {key:?} (expected one of {})",
                    KEYS.join(", ")
                )));
            }
        }
        // The part's constants, then the truth's keys over them, read by the part reader.
        let mut thermal = match serde_yaml::to_value(part.thermal) {
            Ok(Value::Mapping(m)) => m,
            _ => unreachable!("thermal constants serialize to a mapping"),
        };
        match map.get("thermal") {
            None | Some(Value::Null) => {}
            Some(Value::Mapping(over)) => {
                for (k, v) in over {
                    thermal.insert(k.clone(), v.clone());
                }
            }
            Some(_) => {
                return Err(bad(
                    "thermal: expected a mapping of the part's thermal keys".into(),
                ))
            }
        }
        let thermal = ThermalParams::from_yaml(Some(&Value::Mapping(thermal)))
            .map_err(|e| bad(e.to_string()))?;
        let number = |v: &Value, what: &str| -> Result<f64, TruthError> {
            v.as_f64()
                .filter(|x| x.is_finite())
                .ok_or_else(|| bad(format!("{what}: expected a finite number, got {v:?}")))
        };
        let height_factor = match map.get("height_factor") {
            None => 1.0,
            Some(v) => number(v, "height_factor")?,
        };
        let factor_in_range = |f: f64, what: &str| {
            if (0.1..=10.0).contains(&f) {
                Ok(f)
            } else {
                Err(bad(format!("{what}: {f} is outside 0.1 ..= 10")))
            }
        };
        let height_factor = factor_in_range(height_factor, "height_factor")?;
        let zones = match map.get("height_zones") {
            None | Some(Value::Null) => Vec::new(),
            Some(Value::Sequence(s)) => s.clone(),
            Some(v) => {
                return Err(bad(format!(
                    "height_zones: expected a list of {{min_mm, max_mm, factor}}, got {v:?}"
                )))
            }
        };
        let mut height_zones = Vec::new();
        for (i, zone) in zones.iter().enumerate() {
            let corner = |name: &str| -> Result<[f64; 3], TruthError> {
                let what = format!("height_zones[{i}].{name}");
                let list = zone
                    .get(name)
                    .and_then(Value::as_sequence)
                    .filter(|l| l.len() == 3)
                    .ok_or_else(|| bad(format!("{what}: expected [x, y, z] in mm")))?;
                let mut out = [0.0; 3];
                for (o, v) in out.iter_mut().zip(list) {
                    *o = number(v, &what)?;
                }
                Ok(out)
            };
            let (min_mm, max_mm) = (corner("min_mm")?, corner("max_mm")?);
            if (0..3).any(|d| min_mm[d] > max_mm[d]) {
                return Err(bad(format!(
                    "height_zones[{i}]: min_mm {min_mm:?} is above max_mm {max_mm:?} on some axis"
                )));
            }
            let what = format!("height_zones[{i}].factor");
            let factor = zone
                .get("factor")
                .ok_or_else(|| bad(format!("{what}: missing")))
                .and_then(|v| number(v, &what))
                .and_then(|f| factor_in_range(f, &what))?;
            height_zones.push(HeightZone {
                min_mm,
                max_mm,
                factor,
            });
        }
        let mut cut_short = Vec::new();
        let faults = match map.get("cut_short") {
            None | Some(Value::Null) => Vec::new(),
            Some(Value::Sequence(s)) => s.clone(),
            Some(m @ Value::Mapping(_)) => vec![m.clone()],
            Some(v) => {
                return Err(bad(format!(
                    "cut_short: expected {{path, after}} or a list of them, got {v:?}"
                )))
            }
        };
        for (i, f) in faults.iter().enumerate() {
            let field = |name: &str| -> Result<usize, TruthError> {
                f.get(name)
                    .and_then(Value::as_u64)
                    .filter(|&n| n >= 1)
                    .map(|n| n as usize)
                    .ok_or_else(|| {
                        bad(format!(
                            "cut_short[{i}].{name}: expected an integer >= 1, got {:?}",
                            f.get(name)
                        ))
                    })
            };
            cut_short.push(CutShort {
                path: field("path")?,
                after: field("after")?,
            });
        }
        let (mut noise_c, mut seed) = (0.0, 1);
        if let Some(s) = map.get("sensors") {
            if let Some(v) = s.get("noise_c") {
                noise_c = number(v, "sensors.noise_c")?;
                if noise_c < 0.0 {
                    return Err(bad(format!("sensors.noise_c: {noise_c} is negative")));
                }
            }
            if let Some(v) = s.get("seed") {
                seed = v
                    .as_u64()
                    .ok_or_else(|| bad(format!("sensors.seed: expected an integer, got {v:?}")))?;
            }
        }
        Ok(Truth {
            thermal,
            height_factor,
            height_zones,
            cut_short,
            noise_c,
            seed,
        })
    }

    /// The height factor of a deposit centred at `centre_mm` (part frame).
    pub fn height_factor_at(&self, centre_mm: [f64; 3]) -> f64 {
        self.height_zones
            .iter()
            .rev()
            .find(|z| (0..3).all(|d| (z.min_mm[d]..=z.max_mm[d]).contains(&centre_mm[d])))
            .map_or(self.height_factor, |z| z.factor)
    }

    /// How many deposits weld path `path` (1-based) makes before its fault, if it has one.
    pub fn cut_after(&self, path: usize) -> Option<usize> {
        self.cut_short
            .iter()
            .filter(|c| c.path == path)
            .map(|c| c.after)
            .min()
    }
}

/// Gaussian sensor noise from a seed: xorshift64* and Box-Muller, so runs repeat exactly.
#[derive(Debug, Clone)]
pub struct Noise {
    state: u64,
    sigma: f64,
}

impl Noise {
    pub fn new(seed: u64, sigma: f64) -> Noise {
        Noise {
            state: seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1,
            sigma,
        }
    }

    fn uniform(&mut self) -> f64 {
        self.state ^= self.state >> 12;
        self.state ^= self.state << 25;
        self.state ^= self.state >> 27;
        let x = self.state.wrapping_mul(0x2545_F491_4F6C_DD1D);
        ((x >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }

    /// One reading's error, °C.
    pub fn sample(&mut self) -> f64 {
        if self.sigma == 0.0 {
            return 0.0;
        }
        let (u, v) = (self.uniform(), self.uniform());
        self.sigma * (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn part() -> Part {
        Part::parse("name: w\nblock_mm: [6,6,2.5]\nmax_fragments: 2\nlayers: ['##']\nthermal: {conduction_per_s: 0.4}\n").unwrap()
    }

    #[test]
    fn truth_keys_override_the_parts_constants() {
        let t = Truth::parse(
            "thermal: {substrate_per_s: 0.375}\nheight_factor: 0.9\ncut_short: {path: 1, after: 5}\nsensors: {noise_c: 3, seed: 7}\n",
            &part(),
        )
        .unwrap();
        assert_eq!(t.thermal.substrate_per_s, 0.375);
        assert_eq!(t.thermal.conduction_per_s, 0.4);
        assert_eq!(t.height_factor, 0.9);
        assert_eq!(t.cut_after(1), Some(5));
        assert_eq!(t.cut_after(2), None);
        assert_eq!((t.noise_c, t.seed), (3.0, 7));
        assert_eq!(Truth::parse("", &part()).unwrap().thermal, part().thermal);
    }

    #[test]
    fn a_height_zone_gives_the_deposits_in_it_their_own_factor() {
        let t = Truth::parse(
            "height_factor: 0.9\nheight_zones:\n  - {min_mm: [0, -10, 0], max_mm: [6, 10, 100], factor: 0.8}\n  - {min_mm: [5, -10, 0], max_mm: [20, 10, 100], factor: 1.1}\n",
            &part(),
        )
        .unwrap();
        assert_eq!(t.height_factor_at([3.0, 0.0, 1.25]), 0.8);
        // Bounds are inclusive; the later zone wins where two overlap.
        assert_eq!(t.height_factor_at([6.0, 0.0, 1.25]), 1.1);
        assert_eq!(t.height_factor_at([9.0, 0.0, 1.25]), 1.1);
        assert_eq!(t.height_factor_at([30.0, 0.0, 1.25]), 0.9);
    }

    #[test]
    fn a_bad_truth_file_names_the_key() {
        for (text, says) in [
            ("thermal: {conduction: 1}", "unknown key"),
            ("thermal: {substrate_per_s: -1}", "thermal.substrate_per_s"),
            ("height_factor: x", "height_factor"),
            ("height_factor: 0", "outside"),
            ("height_zones: 3", "height_zones: expected a list"),
            (
                "height_zones: [{min_mm: [0, 0], max_mm: [1, 1, 1], factor: 0.9}]",
                "height_zones[0].min_mm",
            ),
            (
                "height_zones: [{min_mm: [2, 0, 0], max_mm: [1, 1, 1], factor: 0.9}]",
                "height_zones[0]: min_mm",
            ),
            (
                "height_zones: [{min_mm: [0, 0, 0], max_mm: [1, 1, 1]}]",
                "height_zones[0].factor: missing",
            ),
            (
                "height_zones: [{min_mm: [0, 0, 0], max_mm: [1, 1, 1], factor: 20}]",
                "outside",
            ),
            ("cut_short: [{path: 0, after: 2}]", "cut_short[0].path"),
            ("sensors: {noise_c: -2}", "negative"),
            ("fault: 1", "unknown key"),
            ("[1, 2]", "mapping"),
        ] {
            let e = Truth::parse(text, &part()).unwrap_err().to_string();
            assert!(e.contains(says), "{text}: {e}");
        }
    }

    #[test]
    fn noise_repeats_with_its_seed_and_has_its_spread() {
        let draw = |seed| {
            let mut n = Noise::new(seed, 5.0);
            (0..4000).map(|_| n.sample()).collect::<Vec<_>>()
        };
        assert_eq!(draw(3), draw(3));
        assert_ne!(draw(3), draw(4));
        let xs = draw(3);
        let mean = xs.iter().sum::<f64>() / xs.len() as f64;
        let sd = (xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / xs.len() as f64).sqrt();
        assert!(mean.abs() < 0.3 && (sd - 5.0).abs() < 0.3, "{mean} {sd}");
    }
}
