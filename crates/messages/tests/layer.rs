//! A layer's simulated temperature field as recorded heat frames (`heat_frames`).

mod common;

const PAPER: &str = "config/layers/paper-16mm.yaml";

#[test]
fn heat_frames_are_thinned_evenly_and_keep_the_last_step() {
    use waam_messages::layer::heat_frames;
    use waam_rosmsg::builtin_interfaces::Time;
    let model = common::layer_model(PAPER);
    let r = common::quick_search(&model);
    let start = Time::from_nanos(1_000_000_000);
    let all = heat_frames(&model, &r.trail, "part", start, 10_000);
    assert_eq!(all.len(), model.horizon);
    let dt_ns = (model.layer.process.time_step_s * 1e9) as i64;
    assert_eq!(
        all.last().unwrap().header.stamp.to_nanos(),
        start.to_nanos() + model.horizon as i64 * dt_ns
    );
    for max in [1, 10, 87] {
        let few = heat_frames(&model, &r.trail, "part", start, max);
        assert!(!few.is_empty() && few.len() <= max, "{max}: {}", few.len());
        assert_eq!(few.last(), all.last(), "{max}");
        // Each kept frame is the full run's frame of the same time step.
        for f in &few {
            assert!(all.contains(f), "{max}");
        }
    }
}
