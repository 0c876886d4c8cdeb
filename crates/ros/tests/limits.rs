//! Issue #18: the node's pipeline within its limits, without DDS — the memory limit as a
//! parameter and before a 1 MB plate is built, a cancel past planning, the motion stage's
//! interrupt (the binary's own limits: `tests/cli/harden.rs`).

use std::sync::Arc;
use std::time::{Duration, Instant};

use waam_fixtures::{plate_layers, stacked_plate, two_towers};
use waam_part::Part;

/// The peak resident memory of this test process (issue #18: never more than 1 GB).
const MAX_RSS_BYTES: u64 = 1 << 30;

/// Issue #18, H2: the node's parameter carries the limit and is checked.
#[test]
fn the_node_parameter_max_memory_mb_is_read_and_checked() {
    use waam_ros::node::params::NodeParams;
    let file = |v: &str| {
        format!("waam_planner:\n  ros__parameters:\n    planner: {{max_memory_mb: {v}}}\n")
    };
    assert_eq!(
        NodeParams::parse(&file("512"))
            .unwrap()
            .planner
            .max_memory_mb,
        512
    );
    let err = NodeParams::parse(&file("0")).unwrap_err().to_string();
    assert!(err.contains("planner.max_memory_mb"), "{err}");
    assert_eq!(
        NodeParams::default().planner.max_memory_mb,
        waam_planner::DEFAULT_MAX_MEMORY_MB as i64
    );
}

/// The node's thread bound is read and checked (0 = all cores; no negative count, no typo
/// of a million threads).
#[test]
fn the_node_parameter_threads_is_read_and_checked() {
    use waam_ros::node::params::NodeParams;
    let file =
        |v: &str| format!("waam_planner:\n  ros__parameters:\n    planner: {{threads: {v}}}\n");
    assert_eq!(NodeParams::parse(&file("1")).unwrap().planner.threads, 1);
    assert_eq!(NodeParams::parse(&file("0")).unwrap().planner.threads, 0);
    for bad in ["-1", "1000000"] {
        let err = NodeParams::parse(&file(bad)).unwrap_err().to_string();
        assert!(err.contains("planner.threads"), "{bad}: {err}");
    }
}

/// Issue #18, H2: the node took 3 GB from a 1 MB message (a 1,000 x 1,000 plate). Its
/// pipeline, with the default parameters and the SAT planner, now answers with the
/// memory-limit error within a second and without the memory.
#[test]
fn the_node_pipeline_refuses_a_1_mb_plate_by_its_memory_limit() {
    use waam_ros::node::params::NodeParams;
    use waam_ros::node::pipeline::{sat_planner, Job, PlanningPipeline};
    use waam_ros::node::worker::{Cancel, JobContext, Pipeline};
    let pipeline = PlanningPipeline::from_params(&NodeParams::default(), sat_planner()).unwrap();
    let document = plate_layers(1000);
    assert!(document.len() > 1_000_000);
    let ctx = JobContext::new(1, Cancel::new(), |_| {});
    let t = Instant::now();
    let input = waam_pipeline::PartInput::Document(document);
    let err = match pipeline.run(Job::from(input), &ctx) {
        Ok(_) => panic!("a 10^6-block plate was planned"),
        Err(e) => e.to_string(),
    };
    assert!(
        err.contains("1000000 blocks") && err.contains("planner.max_memory_mb"),
        "{err}"
    );
    assert!(t.elapsed() < Duration::from_secs(3), "{:?}", t.elapsed());
    // SAFETY: a zeroed rusage is a valid value for getrusage to fill.
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    // SAFETY: usage points to a live local.
    assert_eq!(unsafe { libc::getrusage(libc::RUSAGE_SELF, &mut usage) }, 0);
    let peak = usage.ru_maxrss as u64 * 1024;
    assert!(
        peak < MAX_RSS_BYTES,
        "this test process peaked at {} MB",
        peak >> 20
    );
}

/// Issue #18, H1 (the node past planning): a job whose planner is done goes on to check
/// the plan and plan its motion, which simulate the whole build again; a newer part or a
/// cancelled goal (the cancel flag) now stops that stage within a second too.
#[test]
fn a_cancelled_node_job_stops_within_a_second_past_planning() {
    use waam_ros::node::params::NodeParams;
    use waam_ros::node::pipeline::{Job, JobError, PlanRequest, PlanningPipeline};
    use waam_ros::node::worker::{Cancel, JobContext, Pipeline};
    // The planner's part: the towers' plan, at once (as a planner that found it).
    let planner = Arc::new(|request: &PlanRequest| {
        request.motion(waam_pipeline::ChosenPlan {
            fragments: vec![vec![0], vec![1]],
            stats: Default::default(),
            proven: false,
            worst_margin_s: 0.0,
        })
    });
    let pipeline = PlanningPipeline::from_params(&NodeParams::default(), planner).unwrap();
    let cancel = Cancel::new();
    let ctx = JobContext::new(1, cancel.clone(), |_| {});
    let raiser = std::thread::spawn(move || {
        std::thread::sleep(Duration::from_millis(500));
        cancel.cancel();
        Instant::now()
    });
    let input = waam_pipeline::PartInput::Document(two_towers(5.0e7));
    let result = pipeline.run(Job::from(input), &ctx);
    let stopped = Instant::now();
    let raised = raiser.join().unwrap();
    assert!(
        matches!(result, Err(JobError::Cancelled)),
        "{:?}",
        result.map(|_| ())
    );
    assert!(
        stopped.duration_since(raised) < Duration::from_secs(1),
        "{:?} after the cancel",
        stopped.duration_since(raised)
    );
}

/// Issue #18: the planner's early stop (a first feasible plan) is not a cancel: the stage
/// after it still checks the plan, and a time limit of the library's own stops it.
#[test]
fn the_motion_stage_honours_its_interrupt_and_not_the_planners_stop() {
    use waam_pipeline::{Interrupt, PipelineError};
    let part = Part::parse(&two_towers(5.0e7)).unwrap();
    let cell = waam_ros::node::frames::bundled_cell();
    let found = waam_pipeline::ChosenPlan {
        fragments: vec![vec![0], vec![1]],
        stats: Default::default(),
        proven: false,
        worst_margin_s: 0.0,
    };
    let t = Instant::now();
    let interrupt = Interrupt::after(Some(Duration::from_millis(300)));
    let err = cell.motion_until(part, found, &interrupt).unwrap_err();
    assert!(matches!(err, PipelineError::Interrupted(_)), "{err}");
    assert!(
        err.to_string()
            .starts_with("stopped by the time limit or a cancel while checking"),
        "{err}"
    );
    assert!(
        t.elapsed() < Duration::from_millis(1300),
        "{:?}",
        t.elapsed()
    );
}

/// Issue #30: `plan --robot --timeout 5` on a generated 10,034-block cup answered after
/// 9.5 s: the motion stage (toolpath, inverse kinematics, clearance) never looked at the
/// deadline. On a 20,000-block plate whose check is quick (one Euler step per block, no
/// window) and whose motion takes seconds, the interrupt now stops the motion itself.
#[test]
fn the_motion_stage_stops_inside_the_inverse_kinematics_at_its_interrupt() {
    use waam_pipeline::{Interrupt, PipelineError};
    let (text, plan) = stacked_plate(20, 25, 40);
    let text = text.split("t85:").next().unwrap().to_string()
        + "thermal: {substeps: 1, max_cooldown_s: 0}\n";
    let part = Part::parse(&text).unwrap();
    let order: Vec<usize> = plan
        .split('[')
        .filter_map(|s| s.split(']').next())
        .filter(|s| s.split(',').count() == 3)
        .map(|s| {
            let c: Vec<_> = s.split(',').map(|v| v.trim().parse().unwrap()).collect();
            part.index_of([c[0], c[1], c[2]]).unwrap()
        })
        .collect();
    assert_eq!(order.len(), 20_000);
    let cell = waam_ros::node::frames::bundled_cell();
    let found = waam_pipeline::ChosenPlan {
        fragments: vec![order],
        stats: Default::default(),
        proven: false,
        worst_margin_s: 0.0,
    };
    let t = Instant::now();
    let interrupt = Interrupt::after(Some(Duration::from_millis(1500)));
    let err = cell.motion_until(part, found, &interrupt).unwrap_err();
    assert!(matches!(err, PipelineError::Interrupted(_)), "{err}");
    assert!(
        t.elapsed() < Duration::from_millis(2500),
        "{:?}: {err}",
        t.elapsed()
    );
}
