//! Arbitrary bytes never panic the decoders or the replay: they give an error (property tests).

mod support;

use croprow_core::Point3;
use croprow_io::cloud::{self, PointFormat, Stamped};
use croprow_io::msg::{self, Odometry, PointCloud2, TfMessage};
use croprow_io::read::{Recording, ReplayConfig};
use proptest::prelude::*;

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

    #[test]
    fn random_cdr_never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..512)) {
        let _ = msg::decode::<PointCloud2<'_>>(&bytes).map(|c| cloud::decode(&c, &mut Vec::new()));
        let _ = msg::decode_owned::<Odometry>(&bytes);
        let _ = msg::decode_owned::<TfMessage>(&bytes);
    }

    #[test]
    fn any_layout_round_trips(
        pts in proptest::collection::vec((-100f32..100.0, -100f32..100.0, -10f32..10.0), 0..64),
        xyz_f64: bool, intensity: bool, ring: bool, padding in 0u32..9, big_endian: bool,
    ) {
        let points: Vec<Point3> = pts.iter().map(|&(x, y, z)| Point3::new(x, y, z)).collect();
        let format = PointFormat { xyz_f64, intensity, ring, padding, big_endian };
        let c = cloud::build(&Stamped::new(1.0, "s"), &points, &[], &[], format).unwrap();
        let bytes = if big_endian { msg::encode_big_endian(&c).unwrap() } else { msg::encode(&c).unwrap() };
        let back: PointCloud2<'_> = msg::decode(&bytes).unwrap();
        let mut out = Vec::new();
        cloud::decode(&back, &mut out).unwrap();
        prop_assert_eq!(out, points);
    }

    #[test]
    fn damaged_recordings_never_panic(cut in 8usize..14_000, flips in proptest::collection::vec((0usize..14_000, any::<u8>()), 0..4)) {
        let mut bytes = support::write_fixture(support::Fixture::small(PointFormat::VELODYNE));
        for (at, v) in flips {
            if let Some(b) = bytes.get_mut(at) {
                *b ^= v;
            }
        }
        bytes.truncate(cut);
        let p = support::temp_path(&format!("damaged-{cut}.mcap"));
        std::fs::write(&p, &bytes).unwrap();
        if let Ok(mut replay) = Recording::open(&p).and_then(|r| r.replay(&ReplayConfig::default())) {
            let mut guard = 0;
            while replay.next_scan().is_some() {
                guard += 1;
                prop_assert!(guard < 100, "the replay ends");
            }
        }
        let _ = std::fs::remove_file(&p);
    }
}
