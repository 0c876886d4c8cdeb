//! The constants of the thermal model (the part file's `thermal:` keys), read and checked
//! with the part; the model itself lives in `waam-thermal`.

use serde_yaml::Value;

use crate::finite;

/// A `thermal:` key that is unknown or out of range (the message names it and its value).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{0}")]
pub struct ThermalParamsError(pub String);

/// The most Euler steps one phase (a block, a transit, the cooldown) may take.
pub const MAX_STEPS: u64 = 1_000_000_000;
/// The most Euler steps per block (the spec's default is 20).
pub const MAX_SUBSTEPS: u64 = 1_000_000;

/// The constants of the model: the part's `thermal:` keys.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ThermalParams {
    /// Environment and substrate temperature, °C.
    pub ambient_c: f64,
    /// Temperature of a block at the moment it is deposited, °C.
    pub deposit_c: f64,
    /// Time to deposit one block, s.
    pub block_time_s: f64,
    /// Euler steps per `block_time_s`.
    pub substeps: u32,
    /// Time between the last block of a fragment and the first of the next, s.
    pub transit_time_s: f64,
    /// h: exchange rate between two welded face-neighbours, 1/s.
    pub conduction_per_s: f64,
    /// h_s: exchange rate of a z = 0 block with the substrate, 1/s.
    pub substrate_per_s: f64,
    /// r: radiation coefficient per exposed face, 1/(s·K³).
    pub radiation_per_s_k3: f64,
    /// Longest cooling simulated after the last block, s.
    pub max_cooldown_s: f64,
}

impl Default for ThermalParams {
    fn default() -> Self {
        ThermalParams {
            ambient_c: 20.0,
            deposit_c: 2500.0,
            block_time_s: 1.0,
            substeps: 20,
            transit_time_s: 5.0,
            conduction_per_s: 0.5,
            substrate_per_s: 0.5,
            radiation_per_s_k3: 1.0e-12,
            max_cooldown_s: 3600.0,
        }
    }
}

impl ThermalParams {
    /// Reads the optional `thermal:` mapping of a part file; every key optional.
    pub fn from_yaml(value: Option<&Value>) -> Result<ThermalParams, ThermalParamsError> {
        let mut p = ThermalParams::default();
        let map = match value {
            None | Some(Value::Null) => return Ok(p),
            Some(Value::Mapping(m)) => m,
            Some(other) => {
                return Err(ThermalParamsError(format!(
                    "thermal: expected a mapping, got {}",
                    crate::describe(other)
                )))
            }
        };
        for (key, v) in map {
            let name = key.as_str().unwrap_or("");
            let bad = |what: &str| {
                ThermalParamsError(format!(
                    "thermal.{name}: {what}, got {}",
                    crate::describe(v)
                ))
            };
            if name == "substeps" {
                p.substeps =
                    v.as_u64()
                        .filter(|&n| (1..=u32::MAX as u64).contains(&n))
                        .ok_or_else(|| bad("expected an integer >= 1"))? as u32;
                continue;
            }
            let slot = match name {
                "ambient_c" => &mut p.ambient_c,
                "deposit_c" => &mut p.deposit_c,
                "block_time_s" => &mut p.block_time_s,
                "transit_time_s" => &mut p.transit_time_s,
                "conduction_per_s" => &mut p.conduction_per_s,
                "substrate_per_s" => &mut p.substrate_per_s,
                "radiation_per_s_k3" => &mut p.radiation_per_s_k3,
                "max_cooldown_s" => &mut p.max_cooldown_s,
                _ => {
                    return Err(ThermalParamsError(format!(
                        "thermal: unknown key {}",
                        crate::describe_key(key)
                    )))
                }
            };
            let x = finite(v).ok_or_else(|| bad("expected a finite number"))?;
            if name == "block_time_s" && x <= 0.0 {
                return Err(bad("must be > 0"));
            }
            if !matches!(name, "ambient_c" | "deposit_c") && x < 0.0 {
                return Err(bad("must be >= 0"));
            }
            *slot = x;
        }
        // The spec sets no bound, but a step count beyond a billion is a typo, not a
        // simulation anyone can wait for: name the key rather than run for ever.
        let dt = p.dt();
        // substeps alone sets the steps of every block: blame it, not the durations it
        // multiplies (a billion substeps was reported as a too long transit_time_s).
        if u64::from(p.substeps) > MAX_SUBSTEPS {
            return Err(ThermalParamsError(format!(
                "thermal.substeps: {} Euler steps per block is more than {MAX_SUBSTEPS}; \
                 the simulation would not end",
                p.substeps
            )));
        }
        for (key, seconds) in [
            ("transit_time_s", p.transit_time_s),
            ("max_cooldown_s", p.max_cooldown_s),
            ("block_time_s", p.block_time_s),
        ] {
            if seconds / dt > MAX_STEPS as f64 {
                return Err(ThermalParamsError(format!(
                    "thermal.{key}: {seconds} s is more than {MAX_STEPS} Euler steps of \
                     dt = {dt} s (block_time_s {} s / substeps {}); the simulation would not end",
                    p.block_time_s, p.substeps
                )));
            }
        }
        Ok(p)
    }

    /// The Euler step, s.
    pub fn dt(&self) -> f64 {
        self.block_time_s / self.substeps as f64
    }
}
