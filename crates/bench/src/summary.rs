//! Timed runs summed up per family and size: the solve rate, and the median and worst time
//! to the first plan (a part without a plan in time counts as slower than any with one).

use serde::Serialize;

/// One timed run.
#[derive(Debug, Clone, Serialize)]
pub struct Sample {
    pub family: String,
    /// The size asked for (the family's parts have about this many blocks).
    pub blocks: usize,
    pub seed: u64,
    /// Seconds to the first feasible plan; `None`: none before the timeout.
    pub first_s: Option<f64>,
}

/// The runs of one family at one size.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Summary {
    pub family: String,
    pub blocks: usize,
    pub parts: usize,
    pub solved: usize,
    /// `None` when at least half the parts got no plan in time.
    pub median_s: Option<f64>,
    /// `None` when some part got no plan in time.
    pub worst_s: Option<f64>,
}

impl Summary {
    pub fn rate(&self) -> f64 {
        self.solved as f64 / self.parts.max(1) as f64
    }
}

/// One summary per (family, size), in the order they first appear in `samples`.
pub fn summarize(samples: &[Sample]) -> Vec<Summary> {
    let mut keys: Vec<(&str, usize)> = Vec::new();
    for s in samples {
        if !keys.contains(&(s.family.as_str(), s.blocks)) {
            keys.push((s.family.as_str(), s.blocks));
        }
    }
    keys.into_iter()
        .map(|(family, blocks)| {
            // Unsolved as +inf: they sort last and make the worst unbounded.
            let mut times: Vec<f64> = samples
                .iter()
                .filter(|s| s.family == family && s.blocks == blocks)
                .map(|s| s.first_s.unwrap_or(f64::INFINITY))
                .collect();
            times.sort_by(f64::total_cmp);
            let finite = |t: f64| Some(t).filter(|t| t.is_finite());
            // The lower median of an even count: a plan for at least half the parts.
            let median = times[(times.len() - 1) / 2];
            Summary {
                family: family.to_string(),
                blocks,
                parts: times.len(),
                solved: times.iter().filter(|t| t.is_finite()).count(),
                median_s: finite(median),
                worst_s: finite(*times.last().expect("at least one sample")),
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(family: &str, blocks: usize, first_s: Option<f64>) -> Sample {
        Sample {
            family: family.into(),
            blocks,
            seed: 0,
            first_s,
        }
    }

    #[test]
    fn unsolved_parts_count_as_slowest() {
        let s = summarize(&[
            sample("tube", 1000, Some(3.0)),
            sample("tube", 1000, None),
            sample("tube", 1000, Some(1.0)),
            sample("cup", 1000, Some(2.0)),
            sample("tube", 2000, None),
        ]);
        assert_eq!(s.len(), 3);
        assert_eq!((s[0].family.as_str(), s[0].blocks), ("tube", 1000));
        assert_eq!((s[0].parts, s[0].solved), (3, 2));
        assert_eq!(s[0].median_s, Some(3.0));
        assert_eq!(s[0].worst_s, None);
        assert!((s[0].rate() - 2.0 / 3.0).abs() < 1e-12);
        assert_eq!((s[1].median_s, s[1].worst_s), (Some(2.0), Some(2.0)));
        assert_eq!((s[2].solved, s[2].median_s), (0, None));
    }

    #[test]
    fn an_even_count_takes_the_lower_median() {
        let s = summarize(&[
            sample("cup", 1, Some(4.0)),
            sample("cup", 1, Some(1.0)),
            sample("cup", 1, None),
            sample("cup", 1, Some(2.0)),
        ]);
        assert_eq!(s[0].median_s, Some(2.0));
    }
}
