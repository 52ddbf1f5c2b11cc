//! The rig's final answer: the file engine over the run's own logs (what `calibrate` gives on
//! them), not the live store, which is pruned and rebased as the data come.

use super::inputs::Plan;
use super::RunOptions;
use crate::config::site::Site;
use crate::report::Report;
use spherecal_hal::velodyne::Ports;
use std::path::PathBuf;

/// The calibration of the run's logs (`files`: its pcaps, and its serial logs for a VN-200)
/// as `calibrate` makes it: the same settings, the board's mounting to start from, its ports,
/// model and INS. `None` when nothing was logged.
pub(super) fn final_from_logs(
    opts: &RunOptions,
    site: &Site,
    files: &[PathBuf],
    plan: &Plan,
) -> Result<Option<Report>, crate::Error> {
    let of = |ext: &str| -> Vec<PathBuf> {
        files
            .iter()
            .filter(|p| p.extension().is_some_and(|e| e == ext))
            .cloned()
            .collect()
    };
    let b = &opts.board;
    // An MCAP raw log: one bag folder holds the LiDAR and the serial INS.
    let bag = files.iter().find(|p| p.is_dir()).cloned();
    let pcaps = match &bag {
        Some(d) => vec![d.clone()],
        None => of("pcap"),
    };
    let ins = match (b.ins.kind.as_str(), &bag) {
        ("posmv", Some(d)) => {
            return Err(format!(
                "{}: the POS MV's datagrams in an MCAP raw log are not read back yet: log as pcap (board [log] format = \"pcap\") with a POS MV",
                d.display()
            )
            .into())
        }
        (_, Some(d)) => crate::pipeline::InsInput::Bag(crate::pipeline::Files(vec![d.clone()]), None),
        _ => match b.ins.kind.as_str() {
            "posmv" => crate::pipeline::InsInput::Posmv(
                crate::pipeline::Files(pcaps.clone()),
                None,
                b.ins.posmv_group,
            ),
            _ => crate::pipeline::InsInput::Vn200(crate::pipeline::Files(of("vnlog"))),
        },
    };
    if pcaps.is_empty() || plan.targets.len() < 2 {
        return Ok(None);
    }
    let mut inp =
        crate::pipeline::Inputs::apriori(crate::pipeline::Files(pcaps), ins, site.clone());
    inp.model = b.lidar_model();
    if let Some(p) = &b.lidar.metadata {
        inp.set_metadata(std::path::Path::new(p))?;
    }
    inp.ports = Ports {
        // In an MCAP log the data packets are the scans, which stand for the default port.
        data: match bag {
            Some(_) => spherecal::velodyne::DATA_PORT,
            None => b.lidar.data_port,
        },
        position: b.lidar.position_port,
    };
    inp.keep_untracked_ins = opts.keep_untracked_ins;
    inp.mount = plan.b0.mount();
    let (targets, ids) = crate::calibrate::site_targets(&inp);
    let clock = crate::calibrate::ClockOptions {
        keep_untracked_ins: opts.keep_untracked_ins,
        allow_unlocked: opts.allow_unlocked_clock,
        ..Default::default()
    };
    let (_, _, _, rep) =
        crate::calibrate::calibrate(&mut inp, &targets, &ids, &plan.b0, clock, &mut || {})?;
    Ok(Some(rep))
}
