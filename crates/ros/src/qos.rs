//! Recorded QoS (`waam-rosbag`) as the profile `ros2-client` offers when publishing again.

use waam_rosbag::qos::{Durability, History, Liveliness, Qos, QosTime, Reliability};

/// The profile to offer when publishing again what was recorded (`ros2-client`).
/// Unspecified and infinite durations are both "none"; reliable writes wait up to 5 s for
/// the send window, as the node's do.
pub fn profile(qos: &Qos) -> ros2_client::QosProfile {
    use ros2_client::qos as q;
    let duration = |t: QosTime| {
        (t != QosTime::INFINITE && (t.sec, t.nsec) != (0, 0))
            .then(|| std::time::Duration::new(t.sec, t.nsec.min(999_999_999) as u32))
    };
    let depth = (qos.depth as usize).max(1);
    ros2_client::QosProfile::publisher_default()
        .history(match qos.history {
            History::KeepAll => q::History::KeepAll,
            _ => q::History::KeepLast { depth },
        })
        .reliability(match qos.reliability {
            Reliability::BestEffort => q::Reliability::BestEffort,
            _ => q::Reliability::Reliable {
                when_full: q::WhenFull::Wait(std::time::Duration::from_secs(5)),
            },
        })
        .durability(match qos.durability {
            Durability::TransientLocal => q::Durability::TransientLocal,
            _ => q::Durability::Volatile,
        })
        .deadline(duration(qos.deadline))
        .lifespan(duration(qos.lifespan))
        .liveliness(match qos.liveliness {
            Liveliness::ManualByTopic => q::Liveliness::ManualByTopic,
            _ => q::Liveliness::Automatic,
        })
        .liveliness_lease(duration(qos.liveliness_lease_duration))
}

#[cfg(test)]
mod tests {
    use super::*;
    use ros2_client::qos as q;

    #[test]
    fn recorded_qos_becomes_the_offered_profile() {
        let p = profile(&Qos::latched());
        assert_eq!(p.durability, q::Durability::TransientLocal);
        assert_eq!(p.history, q::History::KeepLast { depth: 1 });
        assert!(matches!(p.reliability, q::Reliability::Reliable { .. }));
        assert_eq!(p.deadline, None);
        let p = profile(&Qos::rosout());
        assert_eq!(p.lifespan, Some(std::time::Duration::from_secs(10)));
        assert_eq!(p.history, q::History::KeepLast { depth: 1000 });
        let p = profile(&Qos::best_effort(5));
        assert_eq!(p.reliability, q::Reliability::BestEffort);
        assert_eq!(p.durability, q::Durability::Volatile);
    }
}
