//! Heat frames of a recorded build; every message a session records decodes and encodes back.

use crate::heat::{heat_frames, HeatOptions, POINT_STEP};
use waam_part::graph::WeldGraph;
use waam_part::Part;
use waam_rosbag::*;
use waam_rosmsg::builtin_interfaces::Time;
use waam_rosmsg::RosMessage;
use waam_thermal::ThermalModel;

const T0: u64 = 1_700_000_000_000_000_000;

#[test]
fn heat_frames_follow_the_build() {
    let part = Part::parse(
        "name: w\nblock_mm: [6,6,2.5]\nmax_fragments: 2\nlayers: ['####', '####']\n\
         t85: [{block: [0,0,0], min_s: 0, max_s: 1000}]\n",
    )
    .unwrap();
    let graph = WeldGraph::new(&part);
    let model = ThermalModel::new(&part, &graph);
    let order: Vec<usize> = (0..part.len()).collect();
    let start = Time::from_nanos(T0 as i64);
    let mut frames = Vec::new();
    heat_frames(
        &part,
        &model,
        &[order],
        "part",
        start,
        HeatOptions::default(),
        |f| {
            frames.push(f);
            Ok::<_, ()>(())
        },
    )
    .unwrap();
    // One frame per block, one after cooldown.
    assert_eq!(frames.len(), part.len() + 1);
    for (i, f) in frames.iter().take(part.len()).enumerate() {
        assert_eq!(f.welded, i + 1);
        assert_eq!(f.cloud.width as usize, i + 1);
        assert_eq!(f.cloud.data.len(), (i + 1) * POINT_STEP as usize);
    }
    let last = frames.last().unwrap();
    assert!(last.time_s > frames[part.len() - 1].time_s);
    // The newest block of frame 3 is the hottest, its position is the block centre (m).
    let f = &frames[2].cloud;
    let point = |k: usize| -> [f32; 4] {
        let p = &f.data[k * 16..k * 16 + 16];
        std::array::from_fn(|j| f32::from_le_bytes(p[j * 4..j * 4 + 4].try_into().unwrap()))
    };
    let newest = point(2);
    let c = part.centre_mm(part.block(2));
    assert!((newest[0] as f64 - c[0] / 1000.0).abs() < 1e-6);
    assert!(newest[3] > point(0)[3]);
    assert_eq!(
        frames[2].cloud.header.stamp.to_nanos(),
        T0 as i64 + (frames[2].time_s * 1e9).round() as i64
    );
    // Fewer frames when asked.
    let mut n = 0;
    heat_frames(
        &part,
        &model,
        &[(0..part.len()).collect()],
        "part",
        start,
        HeatOptions { max_frames: 3 },
        |_| {
            n += 1;
            Ok::<_, ()>(())
        },
    )
    .unwrap();
    // Strides of three blocks (3, 6), the last block (8), and the cooldown.
    assert_eq!(n, 4);
}

#[test]
fn recorded_heat_plays_on_the_build_time_line() {
    let part = Part::parse(crate::sample::PART_TEXT).unwrap();
    let graph = WeldGraph::new(&part);
    let model = ThermalModel::new(&part, &graph);
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("heat");
    let recorder = Recorder::create(&dir).unwrap();
    let start = Time::from_nanos(T0 as i64);
    let order: Vec<usize> = (0..part.len()).collect();
    let n = crate::heat::record_heat(
        &recorder,
        &part,
        &model,
        &[order],
        "part",
        start,
        HeatOptions::default(),
    )
    .unwrap();
    recorder.finish().unwrap();
    let bag = Bag::open(&dir).unwrap();
    let clouds = bag
        .decode_all::<waam_rosmsg::sensor_msgs::PointCloud2>()
        .unwrap();
    assert_eq!(clouds.len(), n);
    assert!(n > part.len() / 2);
    for pair in clouds.windows(2) {
        assert!(pair[0].0 <= pair[1].0);
        assert_eq!(pair[1].0 as i64, pair[1].2.header.stamp.to_nanos());
    }
    // One block time per deposit: the second frame is block_time_s after the first.
    let gap = clouds[1].0 - clouds[0].0;
    assert_eq!(gap, (part.thermal.block_time_s * 1e9).round() as u64);
}

#[test]
fn every_recorded_message_decodes_as_its_type_and_encodes_back_to_the_same_bytes() {
    use waam_rosmsg::dispatch::{visit_type, TypeVisitor};
    struct Reencode<'a>(&'a [u8]);
    impl TypeVisitor for Reencode<'_> {
        type Output = Vec<u8>;
        fn visit<M: RosMessage>(self) -> Vec<u8> {
            waam_rosmsg::to_cdr(&waam_rosmsg::from_cdr::<M>(self.0).unwrap()).unwrap()
        }
    }
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("all");
    let recorder = Recorder::create(&dir).unwrap();
    let mut session = crate::sample::SampleSession::new();
    session.round(&recorder, 0).unwrap();
    recorder.finish().unwrap();
    let bag = Bag::open(&dir).unwrap();
    assert_eq!(bag.topics.len(), 13);
    for m in &bag.messages {
        let t = bag.topic_of(m);
        let again = visit_type(&t.type_name, Reencode(&m.data)).expect("a known type");
        assert_eq!(again, m.data, "{}", t.name);
    }
}
