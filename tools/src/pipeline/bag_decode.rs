//! `spherecal decode` on a ROS 2 bag: its scans (or point clouds) opened as the pipeline
//! opens captures, decoded as a capture's packets are.

use std::path::Path;

/// Decode a ROS 2 bag's scans (`lidar_topic`, else the only `VelodyneScan` topic) as `model`
/// (None: as the packets say, checked against their period); with `csv`, one row per point.
/// A bag that fails while read (cut short) stops the decoding ([`crate::decode::DecodeSummary::stopped`]).
pub fn decode_bag(
    path: &Path,
    lidar_topic: Option<&str>,
    csv: Option<&mut dyn std::io::Write>,
    model: Option<spherecal::velodyne::Model>,
) -> Result<crate::decode::DecodeSummary, crate::decode::DecodeError> {
    let err = crate::decode::DecodeError::at(path);
    let files = crate::pipeline::Files::from(path);
    let open = || {
        crate::pipeline::open_captures(&files, lidar_topic, model)
            .map_err(|e| err(crate::decode::DecodeFailure::Bag(e.to_string())))
    };
    if let crate::pipeline::Captures::Clouds(mut c) = open()? {
        let how = match model {
            Some(_) => "given with --model",
            None => "a point cloud's rings read as a VLP-16's (say --model otherwise)",
        };
        return decode_clouds(&mut c, csv, how)
            .map_err(|e| err(crate::decode::DecodeFailure::Bag(e)));
    }
    let chosen = match model {
        Some(m) => Some((m, "given with --model".into())),
        None => crate::decode::identify_source(open()?, spherecal_hal::velodyne::Ports::default())
            .map_err(|e| err(crate::decode::DecodeFailure::Model(e)))?,
    };
    let mut src = open()?;
    let mut s = crate::decode::decode_packets(&mut src, csv, chosen, |e| {
        Ok::<_, std::io::Error>(e.to_string())
    })
    .map_err(|e| {
        err(crate::decode::DecodeFailure::Pcap(
            spherecal_hal::pcap::PcapError::from(e),
        ))
    })?;
    // An MCAP cut short: what came before its cut was decoded; said as a truncated capture.
    for (_, at) in src.cut() {
        s.skips.count(
            *at,
            &spherecal_hal::packet::SkipReason::TruncatedFile { left: 0 },
        );
    }
    Ok(s)
}

/// Decode a bag's point clouds: their returns (CSV rows as for packets, the packet column
/// numbering chunks of returns, the time the host's in the hour).
fn decode_clouds(
    c: &mut spherecal_hal::rosbag::clouds::CloudChunks,
    mut csv: Option<&mut dyn std::io::Write>,
    how: &str,
) -> Result<crate::decode::DecodeSummary, String> {
    let model = c.model();
    let mut s = crate::decode::DecodeSummary {
        model: Some((model, how.into())),
        ..Default::default()
    };
    let io = |e: std::io::Error| e.to_string();
    if let Some(w) = csv.as_deref_mut() {
        writeln!(w, "{}", crate::decode::CSV_HEADER).map_err(io)?;
    }
    let mut chunk = spherecal_hal::rosbag::clouds::Chunk::default();
    let mut line = Vec::with_capacity(64 * 96);
    const HOUR_NS: i64 = 3_600_000_000_000;
    loop {
        match c.next_chunk(&mut chunk) {
            Ok(true) => {}
            Ok(false) => break,
            Err(e) => {
                s.stopped = Some(e.to_string());
                break;
            }
        }
        if let Some(w) = csv.as_deref_mut() {
            let ts = chunk.t0.0.rem_euclid(HOUR_NS) as u64;
            crate::decode::write_rows(w, &mut line, s.data_packets, ts, model, chunk.points())
                .map_err(io)?;
        }
        s.points += chunk.points().len() as u64;
        s.data_packets += 1;
    }
    if let Some(w) = csv {
        w.flush().map_err(io)?;
    }
    s.clouds = Some(c.stats.clouds);
    s.skips = c.stats.skips.clone();
    Ok(s)
}
