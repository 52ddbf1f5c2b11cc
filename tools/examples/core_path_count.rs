//! A fixed amount of core-path work (decode -> align -> georef -> window over the MRPT capture,
//! 20 times) for deterministic instruction counts: `valgrind --tool=callgrind
//! target/release/examples/core_path_count` (criterion timings on a shared machine swing).

use spherecal::align::window::Batch;
use spherecal::velodyne::PointBuf;
use spherecal_tools::fixtures::CorePath;

fn main() {
    let w = CorePath::load();
    let mut points = PointBuf::new();
    let mut batches: Vec<Batch<1024>> = (0..2).map(|_| Batch::default()).collect();
    let n: u64 = (0..20).map(|_| w.run(&mut points, &mut batches)).sum();
    println!("{n} returns");
}
