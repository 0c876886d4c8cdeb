//! The cell's sensors in (#31): a layer height scan (`sensor_msgs/PointCloud2`, e.g. from a
//! The cell's sensors in (#31): a layer height scan (`sensor_msgs/PointCloud2`, e.g. from a
//! laser line scanner after each layer) on `closed_loop.scan_topic`, a pyrometer
//! (`sensor_msgs/Temperature`) on `closed_loop.temperature_topic`, a thermal camera's image
//! mapped onto the part (`sensor_msgs/PointCloud2` with a `temperature` field, °C) on
//! `closed_loop.thermal_camera_topic`, and the welding power source's arc faults
//! (`std_msgs/Header`, stamped when the arc went out) on `closed_loop.arc_fault_topic`. Each
//! message is recorded as it came, checked ([`waam_messages::sensor`]) and, when good, handed
//! to the closed loop as a [`Measured`] (an arc fault to the execution at once,
//! [`ArcFaults`]); every verdict goes to the event loop, which reports it on `/diagnostics`.
//! A cloud may come in any frame `/tf` and `/tf_static` connect to the robot's base link: the
//! sensor thread keeps their frame tree ([`TfBuffer`]) and places each cloud at its stamp.

use std::sync::mpsc::Sender;
use std::sync::{Arc, Mutex};

use futures::StreamExt;
use ros2_client::{Node, Subscription};

use super::arc_fault::ArcFaults;
use super::frames::TF_STATIC;
use super::io::{sensor_qos, stream_qos, subscribe, tf_qos, tf_static_qos, IoError};
use super::names::NodeNames;
use super::params::ClosedLoopParams;
use super::pipeline::Planned;
use waam_cell::Measured;
use waam_messages::sensor::{self, ScanTarget};
use waam_messages::tf_buffer::{TfBuffer, TfError};
use waam_rosbag::qos::Qos;
use waam_rosbag::Recorder;
use waam_rosmsg::builtin_interfaces::Time;
use waam_rosmsg::sensor_msgs::{PointCloud2, Temperature};
use waam_rosmsg::std_msgs::Header;
use waam_rosmsg::tf2_msgs::TFMessage;
use waam_rosmsg::RosMessage;

/// The dynamic transforms' topic (tf2's; `/tf_static` is [`TF_STATIC`]).
pub const TF: &str = "/tf";

/// Which sensor a message came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SensorKind {
    Scan,
    Temperature,
    ThermalCamera,
    /// The welding power source's arc faults.
    ArcFault,
}

impl SensorKind {
    pub const ALL: [SensorKind; 4] = [
        SensorKind::Scan,
        SensorKind::Temperature,
        SensorKind::ThermalCamera,
        SensorKind::ArcFault,
    ];

    pub fn name(self) -> &'static str {
        match self {
            SensorKind::Scan => "scan",
            SensorKind::Temperature => "temperature",
            SensorKind::ThermalCamera => "thermal camera",
            SensorKind::ArcFault => "arc fault",
        }
    }

    /// Its name in the `closed_loop.*` parameters.
    pub fn parameter(self) -> &'static str {
        match self {
            SensorKind::Scan => "scan",
            SensorKind::Temperature => "temperature",
            SensorKind::ThermalCamera => "thermal_camera",
            SensorKind::ArcFault => "arc_fault",
        }
    }
}

/// What a sensor's latest message told.
#[derive(Debug, Clone, PartialEq)]
pub enum Verdict {
    /// Subscribed, nothing received yet.
    Waiting,
    /// Used; a one-line summary.
    Good(String),
    /// Not used, and why.
    Bad(String),
}

/// One sensor's news for the node's health.
#[derive(Debug, Clone, PartialEq)]
pub struct SensorNews {
    pub topic: String,
    pub kind: SensorKind,
    pub verdict: Verdict,
}

/// The part scans are checked against: the latest plan's, which the event loop sets.
#[derive(Clone)]
pub struct ScanTargets {
    base_link: String,
    current: Arc<Mutex<Option<ScanTarget>>>,
}

impl ScanTargets {
    /// No part yet; `base_link` is the robot's (scans may come in it).
    pub fn new(base_link: &str) -> ScanTargets {
        ScanTargets {
            base_link: base_link.to_string(),
            current: Arc::default(),
        }
    }

    /// Scans from now on are of `planned`'s part, on its plate.
    pub fn measure(&self, planned: &Planned) {
        let target = ScanTarget::of_part(&planned.part, &self.base_link, planned.plate);
        *self.current.lock().unwrap_or_else(|e| e.into_inner()) = Some(target);
    }

    fn current(&self) -> Option<ScanTarget> {
        self.current
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .clone()
    }
}

/// Where the sensor thread hands its data: the closed loop's channel, and the part scans
/// are checked against.
pub struct Wiring {
    pub measured: Sender<Measured>,
    pub targets: ScanTargets,
    pub faults: ArcFaults,
}

/// The three sensor subscriptions, the frames clouds may come in, and how their data is
/// judged.
pub struct Sensors {
    pub scan_topic: String,
    scan: Subscription<PointCloud2>,
    pub temperature_topic: String,
    temperature: Subscription<Temperature>,
    pub camera_topic: String,
    camera: Subscription<PointCloud2>,
    pub arc_fault_topic: String,
    arc_fault: Subscription<Header>,
    tf: Subscription<TFMessage>,
    tf_static: Subscription<TFMessage>,
    limits: ClosedLoopParams,
}

enum Incoming {
    Scan(PointCloud2),
    Temperature(Temperature),
    Image(PointCloud2),
    ArcFault(Header),
    /// Transforms (or why a message on the topic could not be read), from `/tf_static`
    /// when `fixed`.
    Frames {
        msg: Result<TFMessage, TfError>,
        fixed: bool,
    },
}

impl Sensors {
    pub fn new(
        node: &mut Node,
        names: &NodeNames,
        params: &ClosedLoopParams,
    ) -> Result<Sensors, IoError> {
        let (scan_topic, scan) = subscribe(node, names, &params.scan_topic, sensor_qos())?;
        let (temperature_topic, temperature) =
            subscribe(node, names, &params.temperature_topic, sensor_qos())?;
        let (camera_topic, camera) =
            subscribe(node, names, &params.thermal_camera_topic, sensor_qos())?;
        // Reliable: a fault lost is a weld path welded on as if the arc burned.
        let (arc_fault_topic, arc_fault) =
            subscribe(node, names, &params.arc_fault_topic, arc_fault_qos())?;
        let (_, tf) = subscribe(node, names, TF, tf_qos())?;
        let (_, tf_static) = subscribe(node, names, TF_STATIC, tf_static_qos())?;
        Ok(Sensors {
            scan_topic,
            scan,
            temperature_topic,
            temperature,
            camera_topic,
            camera,
            arc_fault_topic,
            arc_fault,
            tf,
            tf_static,
            limits: params.clone(),
        })
    }

    /// Starts the sensor thread: good data goes to `measured`, every verdict to `news`; the
    /// thread ends when `news` says the event loop is gone.
    pub fn spawn(
        self,
        wiring: Wiring,
        news: impl Fn(SensorNews) -> bool + Send + 'static,
        recorder: Option<Recorder>,
    ) -> std::io::Result<()> {
        let Wiring {
            measured,
            targets,
            faults,
        } = wiring;
        let Sensors {
            scan_topic,
            scan,
            temperature_topic,
            temperature,
            camera_topic,
            camera,
            arc_fault_topic,
            arc_fault,
            tf,
            tf_static,
            limits,
        } = self;
        let topic = move |kind| match kind {
            SensorKind::Scan => scan_topic.clone(),
            SensorKind::Temperature => temperature_topic.clone(),
            SensorKind::ThermalCamera => camera_topic.clone(),
            SensorKind::ArcFault => arc_fault_topic.clone(),
        };
        let record = move |topic: &str, message: &dyn Fn(&Recorder, &str) -> RecordResult| {
            if let Some(r) = &recorder {
                if let Err(e) = message(r, topic) {
                    tracing::warn!("recording {topic}: {e}");
                }
            }
        };
        std::thread::Builder::new()
            .name("ros-sensors".into())
            .spawn(move || {
                for kind in SensorKind::ALL {
                    let verdict = Verdict::Waiting;
                    if !news(SensorNews {
                        topic: topic(kind),
                        kind,
                        verdict,
                    }) {
                        return;
                    }
                }
                let scans = scan
                    .async_stream()
                    .map(|r| (SensorKind::Scan, r.map(|(m, _)| Incoming::Scan(m))));
                let temperatures = temperature.async_stream().map(|r| {
                    (
                        SensorKind::Temperature,
                        r.map(|(m, _)| Incoming::Temperature(m)),
                    )
                });
                let images = camera.async_stream().map(|r| {
                    (
                        SensorKind::ThermalCamera,
                        r.map(|(m, _)| Incoming::Image(m)),
                    )
                });
                // Transforms are for the scans; what is wrong with them goes to the log.
                let frames_of = |fixed| {
                    move |r: ros2_client::ReadResult<(TFMessage, _)>| {
                        let msg = r
                            .map(|(msg, _)| msg)
                            .map_err(|e| TfError::Unreadable(e.to_string()));
                        (SensorKind::Scan, Ok(Incoming::Frames { msg, fixed }))
                    }
                };
                let arc_faults = arc_fault
                    .async_stream()
                    .map(|r| (SensorKind::ArcFault, r.map(|(m, _)| Incoming::ArcFault(m))));
                let mut merged = futures::stream::select_all([
                    scans.boxed(),
                    temperatures.boxed(),
                    images.boxed(),
                    arc_faults.boxed(),
                    tf.async_stream().map(frames_of(false)).boxed(),
                    tf_static.async_stream().map(frames_of(true)).boxed(),
                ]);
                let mut frames = TfBuffer::default();
                let mut warned = std::collections::BTreeSet::new();
                futures::executor::block_on(async {
                    while let Some((kind, item)) = merged.next().await {
                        let topic = topic(kind);
                        let judged = match item {
                            Ok(Incoming::Frames { msg, fixed }) => {
                                let on = if fixed { TF_STATIC } else { TF };
                                let faults = match msg {
                                    Ok(msg) => {
                                        // Recorded, so that `waam replay` places the scans
                                        // again as the node did.
                                        let qos = if fixed {
                                            Qos::latched()
                                        } else {
                                            Qos::reliable(100)
                                        };
                                        record(on, &|r, t| r.record(t, &qos, &msg));
                                        frames.add(&msg, fixed)
                                    }
                                    Err(e) => vec![e],
                                };
                                // Once per pair of frames (or kind of fault): /tf runs at
                                // 100 Hz, and the set stays as small as the frame tree.
                                for fault in faults {
                                    if warned.insert(fault.frames()) {
                                        tracing::warn!("{on}: {fault}");
                                    }
                                }
                                continue;
                            }
                            Ok(Incoming::Scan(cloud)) => {
                                record(&topic, &|r, t| r.record(t, &Qos::best_effort(10), &cloud));
                                unless_panicked(|| judge_scan(&cloud, &targets, &frames, &limits))
                            }
                            Ok(Incoming::Image(cloud)) => {
                                record(&topic, &|r, t| r.record(t, &Qos::best_effort(10), &cloud));
                                unless_panicked(|| judge_image(&cloud, &targets, &frames, &limits))
                            }
                            Ok(Incoming::Temperature(reading)) => {
                                record(&topic, &|r, t| {
                                    r.record(t, &Qos::best_effort(10), &reading)
                                });
                                unless_panicked(|| judge_temperature(&reading, &limits))
                            }
                            Ok(Incoming::ArcFault(header)) => {
                                record(&topic, &|r, t| {
                                    r.record(t, &arc_fault_qos_recorded(), &header)
                                });
                                let verdict =
                                    match sensor::arc_fault(&header, Time::now(), limits.max_age_s)
                                    {
                                        Ok(stamp_s) => {
                                            let stopped = faults.report(stamp_s);
                                            Verdict::Good(format!(
                                                "the arc went out at {stamp_s:.3} s: {}",
                                                if stopped {
                                                    "the weld path stops, the rest is re-planned"
                                                } else {
                                                    "no closed-loop weld goal was running: nothing stopped"
                                                }
                                            ))
                                        }
                                        Err(e) => Verdict::Bad(e.to_string()),
                                    };
                                if !news(SensorNews {
                                    topic,
                                    kind,
                                    verdict,
                                }) {
                                    return;
                                }
                                continue;
                            }
                            // A message that does not decode (another type on the topic).
                            Err(e) => Err(Rejected::Undecodable {
                                type_name: type_of(kind),
                                msg: e.to_string(),
                            }),
                        };
                        let verdict = match judged {
                            Ok((reading, summary)) => {
                                // Nobody listening any more only happens while stopping.
                                let _ = measured.send(reading);
                                Verdict::Good(summary)
                            }
                            Err(reason) => Verdict::Bad(reason.to_string()),
                        };
                        if !news(SensorNews {
                            topic,
                            kind,
                            verdict,
                        }) {
                            return;
                        }
                    }
                });
            })?;
        Ok(())
    }
}

/// Arc faults are few and each one matters: reliable (a publisher must be too), keep last
/// 10 ([`stream_qos`]).
fn arc_fault_qos() -> ros2_client::QosProfile {
    stream_qos()
}

fn arc_fault_qos_recorded() -> Qos {
    Qos::reliable(10)
}

type RecordResult = Result<(), waam_rosbag::BagError>;

fn type_of(kind: SensorKind) -> &'static str {
    match kind {
        SensorKind::Scan | SensorKind::ThermalCamera => PointCloud2::TYPE_NAME,
        SensorKind::Temperature => Temperature::TYPE_NAME,
        SensorKind::ArcFault => Header::TYPE_NAME,
    }
}

/// Why a sensor message was not taken.
#[derive(Debug, thiserror::Error)]
enum Rejected {
    #[error("cannot read a {type_name} message: {msg}")]
    Undecodable {
        type_name: &'static str,
        msg: String,
    },
    #[error(transparent)]
    Bad(#[from] sensor::BadReading),
    #[error("internal error while checking it (a bug: please report)")]
    Panicked,
}

/// A reading the closed loop takes, with a summary for `/diagnostics`.
type Judged = Result<(Measured, String), Rejected>;

/// `judge()`, or a reason when it panicked: a bug in a check must not end the sensor thread
/// (the sensors would fall silent while the node runs on).
fn unless_panicked(judge: impl FnOnce() -> Judged) -> Judged {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(judge)).unwrap_or(Err(Rejected::Panicked))
}

/// A scan as the closed loop takes it, with a summary; or why not.
fn judge_scan(
    cloud: &PointCloud2,
    targets: &ScanTargets,
    frames: &TfBuffer,
    limits: &ClosedLoopParams,
) -> Judged {
    let target = targets.current();
    let good = sensor::scan(
        cloud,
        target.as_ref(),
        frames,
        limits.scan_margin_mm,
        Time::now(),
        limits.max_age_s,
    )?;
    let top = good
        .points
        .iter()
        .map(|p| p[2])
        .fold(f64::NEG_INFINITY, f64::max);
    let summary = format!(
        "{} points on the part ({} off it dropped), top at {top:.2} mm",
        good.points.len(),
        good.dropped
    );
    Ok((good.measured(), summary))
}

/// A thermal image as the closed loop takes it, with a summary; or why not.
fn judge_image(
    cloud: &PointCloud2,
    targets: &ScanTargets,
    frames: &TfBuffer,
    limits: &ClosedLoopParams,
) -> Judged {
    let target = targets.current();
    let good = sensor::thermal_image(
        cloud,
        target.as_ref(),
        frames,
        limits.scan_margin_mm,
        Time::now(),
        limits.max_age_s,
    )?;
    let hottest = good
        .points
        .iter()
        .map(|p| p.1)
        .fold(f64::NEG_INFINITY, f64::max);
    let summary = format!(
        "{} points read on the part ({} off it dropped, {} unread), hottest {hottest:.1} °C",
        good.points.len(),
        good.dropped,
        good.unread
    );
    Ok((good.measured(), summary))
}

/// A pyrometer reading as the closed loop takes it, with a summary; or why not.
fn judge_temperature(reading: &Temperature, limits: &ClosedLoopParams) -> Judged {
    let measured = sensor::temperature(reading, Time::now(), limits.max_age_s)?;
    Ok((measured, format!("{:.1} °C", reading.temperature)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_panicking_check_is_a_reason_not_a_dead_thread() {
        let e = unless_panicked(|| panic!("a bug")).unwrap_err().to_string();
        assert!(e.contains("internal error"), "{e}");
        let ok = unless_panicked(|| {
            Ok((
                Measured::Temperature {
                    stamp_s: 1.0,
                    celsius: 2.0,
                },
                "2.0 °C".into(),
            ))
        });
        assert_eq!(ok.unwrap().1, "2.0 °C");
    }
}
