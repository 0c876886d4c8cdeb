//! The node's health on `/diagnostics` (diagnostic_msgs/DiagnosticArray) once a second, as
//! diagnostic_updater nodes report it: a monitor tells a stale node by the silence, and reads
//! the state and the last result without having seen the events on `~/status`. Each sensor
//! of the closed loop is a component of its own: OK while its data is used, WARN naming the
//! topic and the reason while it is not, or while an execution runs and it has been silent
//! for longer than its cadence (`closed_loop.*_period_s`).

use std::collections::BTreeMap;
use std::time::{Duration, Instant};

use super::sensors::{SensorKind, SensorNews, Verdict};
use waam_messages::status::Status;
use waam_rosmsg::builtin_interfaces::Time;
use waam_rosmsg::diagnostic_msgs::{DiagnosticArray, DiagnosticStatus, KeyValue};

pub const DIAGNOSTICS: &str = "/diagnostics";
/// How often the health goes out.
pub const PERIOD: Duration = Duration::from_secs(1);

/// How a job ended.
#[derive(Debug, Clone, PartialEq)]
pub enum Outcome {
    /// A plan, summarised.
    Planned(String),
    /// No plan, and why.
    NoPlan(String),
}

/// What the event loop knows about the node's work.
pub struct Health {
    /// `/namespace/name`: the status's hardware id; `name: planner` its name.
    node: String,
    started: Instant,
    /// The job being planned, if any.
    pub planning: Option<u64>,
    /// The last finished job and its outcome.
    pub last: Option<(u64, Outcome)>,
    pub planned: u64,
    pub failed: u64,
    /// The sensors by topic.
    sensors: BTreeMap<String, SensorHealth>,
    /// The cadence of the scanner, the pyrometer and the camera (`SensorKind::ALL`'s
    /// first three), s; 0: none expected.
    periods_s: [f64; 3],
}

/// What a sensor's messages told so far.
struct SensorHealth {
    kind: SensorKind,
    verdict: Verdict,
    used: u64,
    rejected: u64,
    /// Kept after good data clears the WARN, so a passing fault still shows.
    last_rejected: Option<String>,
    /// When its last message came.
    last_message: Option<Instant>,
    /// Silent for longer than its cadence while an execution runs: for how long, s.
    silent_s: Option<f64>,
}

impl Health {
    /// The health of `node`, whose scanner, pyrometer and camera publish at least every
    /// `periods_s` (0: at no set cadence) while an execution runs.
    pub fn new(node: String, periods_s: [f64; 3]) -> Health {
        Health {
            node,
            started: Instant::now(),
            planning: None,
            last: None,
            planned: 0,
            failed: 0,
            sensors: BTreeMap::new(),
            periods_s,
        }
    }

    /// A sensor kind's cadence; arc faults are events, never expected at one.
    fn period_s(&self, kind: SensorKind) -> f64 {
        let i = SensorKind::ALL.iter().position(|&k| k == kind);
        i.and_then(|i| self.periods_s.get(i))
            .copied()
            .unwrap_or(0.0)
    }

    /// Checks each sensor's cadence at `now`, an execution running since `executing`:
    /// returns the sensors that fell silent (WARN) or spoke again (OK) since the last check.
    pub fn cadence(&mut self, executing: Option<Instant>, now: Instant) -> Vec<(u8, String)> {
        let periods: Vec<f64> = self
            .sensors
            .values()
            .map(|s| self.period_s(s.kind))
            .collect();
        let mut changes = Vec::new();
        for ((topic, s), period_s) in self.sensors.iter_mut().zip(periods) {
            let silent_s = executing.filter(|_| period_s > 0.0).and_then(|since| {
                let from = s.last_message.map_or(since, |m| m.max(since));
                let silent = now.saturating_duration_since(from).as_secs_f64();
                (silent > period_s).then_some(silent)
            });
            match (s.silent_s.is_some(), silent_s.is_some()) {
                (false, true) => changes.push((
                    DiagnosticStatus::WARN,
                    format!(
                        "{topic}: {}",
                        silence(silent_s.unwrap_or(0.0), period_s, s.kind)
                    ),
                )),
                (true, false) if executing.is_some() => {
                    changes.push((DiagnosticStatus::OK, format!("{topic}: data again")))
                }
                _ => {}
            }
            s.silent_s = silent_s;
        }
        changes
    }

    /// Takes a sensor's news. Returns what changed worth saying at once (and logging): the
    /// sensor went bad or bad for another reason (WARN), or it is good again (OK).
    pub fn sensor(&mut self, news: SensorNews) -> Option<(u8, String)> {
        let s = self
            .sensors
            .entry(news.topic.clone())
            .or_insert_with(|| SensorHealth {
                kind: news.kind,
                verdict: Verdict::Waiting,
                used: 0,
                rejected: 0,
                last_rejected: None,
                last_message: None,
                silent_s: None,
            });
        if news.verdict != Verdict::Waiting {
            s.last_message = Some(Instant::now());
        }
        let was_bad = matches!(s.verdict, Verdict::Bad(_));
        let change = match &news.verdict {
            Verdict::Waiting => None,
            Verdict::Good(summary) => {
                s.used += 1;
                was_bad.then(|| (DiagnosticStatus::OK, format!("{}: {summary}", news.topic)))
            }
            Verdict::Bad(reason) => {
                s.rejected += 1;
                s.last_rejected = Some(reason.clone());
                (s.verdict != news.verdict)
                    .then(|| (DiagnosticStatus::WARN, format!("{}: {reason}", news.topic)))
            }
        };
        s.verdict = news.verdict;
        change
    }

    /// The health now: OK, or WARN when the last part got no plan.
    pub fn to_msg(&self, stamp: Time) -> DiagnosticArray {
        let state = match self.planning {
            Some(job) => format!("planning part {job}"),
            None => "idle".to_string(),
        };
        let (level, last) = match &self.last {
            None => (DiagnosticStatus::OK, "no part yet".to_string()),
            Some((job, Outcome::Planned(summary))) => {
                (DiagnosticStatus::OK, format!("part {job}: {summary}"))
            }
            Some((job, Outcome::NoPlan(reason))) => (
                DiagnosticStatus::WARN,
                format!("part {job}: no plan: {reason}"),
            ),
        };
        let mut values = vec![
            KeyValue::new("state", &state),
            KeyValue::new("last_result", &last),
            KeyValue::new("parts_planned", self.planned),
            KeyValue::new("parts_failed", self.failed),
            KeyValue::new(
                "uptime_s",
                format!("{:.0}", self.started.elapsed().as_secs_f64()),
            ),
        ];
        if let Some(job) = self.planning {
            values.push(KeyValue::new("job", job));
        }
        let node = self.node.trim_start_matches('/');
        let mut msg = Status::new(level, format!("{state}; last: {last}"), values).reported_by(
            stamp,
            &format!("{node}: planner"),
            &self.node,
        );
        for (topic, s) in &self.sensors {
            msg.status.push(
                s.status(topic, self.period_s(s.kind))
                    .diagnostic(&format!("{node}: {} sensor", s.kind.name()), &self.node),
            );
        }
        msg
    }
}

impl SensorHealth {
    /// OK while the latest message was used (or none came yet), WARN naming the topic and
    /// the reason while it was not, or while it is silent for longer than its cadence.
    fn status(&self, topic: &str, period_s: f64) -> Status {
        let (level, message) = match (&self.verdict, self.silent_s) {
            (_, Some(silent_s)) => (
                DiagnosticStatus::WARN,
                silence(silent_s, period_s, self.kind),
            ),
            (Verdict::Waiting, None) => (DiagnosticStatus::OK, "no data yet".to_string()),
            (Verdict::Good(summary), None) => (DiagnosticStatus::OK, summary.clone()),
            (Verdict::Bad(reason), None) => (DiagnosticStatus::WARN, reason.clone()),
        };
        let mut values = vec![
            KeyValue::new("topic", topic),
            KeyValue::new("used", self.used),
            KeyValue::new("rejected", self.rejected),
        ];
        if let Some(reason) = &self.last_rejected {
            values.push(KeyValue::new("last_rejected", reason));
        }
        Status::new(level, format!("{topic}: {message}"), values)
    }
}

/// What a silent sensor's status says.
fn silence(silent_s: f64, period_s: f64, kind: SensorKind) -> String {
    format!(
        "silent: no message for {silent_s:.1} s while executing (expected every {period_s} s: \
         closed_loop.{}_period_s)",
        kind.parameter()
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn state_and_last_result() {
        let mut h = Health::new("/cell1/waam_planner".into(), [0.0; 3]);
        let msg = h.to_msg(Time::default());
        assert_eq!(msg.status[0].name, "cell1/waam_planner: planner");
        assert_eq!(msg.status[0].level, DiagnosticStatus::OK);
        h.planning = Some(2);
        h.last = Some((1, Outcome::NoPlan("cancelled".into())));
        let s = &h.to_msg(Time::default()).status[0];
        assert_eq!(s.level, DiagnosticStatus::WARN);
        assert_eq!(
            s.message,
            "planning part 2; last: part 1: no plan: cancelled"
        );
    }

    #[test]
    fn a_sensor_warns_with_its_topic_and_reason_until_good_data_comes() {
        let mut h = Health::new("/cellX/waam_planner".into(), [0.0; 3]);
        let news = |verdict| SensorNews {
            topic: "/cellX/waam_planner/temperature".into(),
            kind: SensorKind::Temperature,
            verdict,
        };
        assert_eq!(h.sensor(news(Verdict::Waiting)), None);
        let s = &h.to_msg(Time::default()).status[1];
        assert_eq!(s.name, "cellX/waam_planner: temperature sensor");
        assert_eq!(
            (s.level, s.message.as_str()),
            (
                DiagnosticStatus::OK,
                "/cellX/waam_planner/temperature: no data yet"
            )
        );
        let bad = Verdict::Bad("temperature 5000 °C is outside the plausible range".into());
        let change = h.sensor(news(bad.clone())).unwrap();
        assert_eq!(change.0, DiagnosticStatus::WARN);
        assert_eq!(
            h.sensor(news(bad)),
            None,
            "the same reason again is no news"
        );
        let s = &h.to_msg(Time::default()).status[1];
        assert_eq!(s.level, DiagnosticStatus::WARN);
        assert_eq!(
            s.message,
            "/cellX/waam_planner/temperature: temperature 5000 °C is outside the plausible range"
        );
        assert!(s.values.contains(&KeyValue::new("rejected", 2)));
        let change = h.sensor(news(Verdict::Good("612.0 °C".into())));
        assert_eq!(change.map(|c| c.0), Some(DiagnosticStatus::OK));
        let s = &h.to_msg(Time::default()).status[1];
        assert_eq!(s.level, DiagnosticStatus::OK);
        assert_eq!(s.message, "/cellX/waam_planner/temperature: 612.0 °C");
        assert!(s.values.iter().any(|kv| kv.key == "last_rejected"));
        assert_eq!(
            h.to_msg(Time::default()).status[0].level,
            DiagnosticStatus::OK
        );
    }

    #[test]
    fn a_sensor_silent_for_longer_than_its_cadence_while_executing_warns() {
        // The pyrometer every 0.5 s, the scanner at no cadence.
        let mut h = Health::new("/cellX/waam_planner".into(), [0.0, 0.5, 0.0]);
        for (topic, kind) in [("t", SensorKind::Temperature), ("s", SensorKind::Scan)] {
            h.sensor(SensorNews {
                topic: topic.into(),
                kind,
                verdict: Verdict::Waiting,
            });
        }
        let t0 = Instant::now();
        // Idle: silence is no news.
        assert!(h.cadence(None, t0 + Duration::from_secs(60)).is_empty());
        // Executing since t0: silent 0.4 s is within the cadence, 0.7 s not.
        assert!(h
            .cadence(Some(t0), t0 + Duration::from_millis(400))
            .is_empty());
        let change = h.cadence(Some(t0), t0 + Duration::from_millis(700));
        assert_eq!(change.len(), 1, "{change:?}");
        assert_eq!(change[0].0, DiagnosticStatus::WARN);
        assert!(
            change[0].1.starts_with("t: silent: no message for 0.7 s")
                && change[0].1.contains("closed_loop.temperature_period_s"),
            "{change:?}"
        );
        let s = h
            .to_msg(Time::default())
            .status
            .into_iter()
            .find(|s| s.name.ends_with("temperature sensor"))
            .unwrap();
        assert_eq!(s.level, DiagnosticStatus::WARN);
        // A reading ends the silence.
        h.sensor(SensorNews {
            topic: "t".into(),
            kind: SensorKind::Temperature,
            verdict: Verdict::Good("650.0 °C".into()),
        });
        let change = h.cadence(Some(t0), Instant::now());
        assert_eq!(change, vec![(DiagnosticStatus::OK, "t: data again".into())]);
        assert_eq!(
            h.to_msg(Time::default()).status[2].level,
            DiagnosticStatus::OK
        );
    }
}
