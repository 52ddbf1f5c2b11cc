//! A data packet's reach without decoding it: how many returns [`decode_as`] gives and the
//! azimuths each block's firings span. The windowing turns away a packet whose azimuths miss
//! every window (`align::window::Windowing::beyond_reach`) before any point is computed:
//! calibration keeps only the returns near the spheres, a few percent of a scan.

use super::data::field::{BLOCKS, CHANNELS};
#[cfg(doc)]
use super::firing::decode_as;
use super::firing::{azimuth_cdeg, mode_and_gaps, CDEG_TO_RAD};
use super::model::Model;
use super::{DataPacket, Error, POINTS_PER_PACKET};

/// What [`extent`] finds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Extent {
    /// The returns [`decode_as`] would give.
    pub returns: usize,
    /// Each block's firings' azimuths, lowest and highest [rad] (clockwise from +y, as the
    /// points'; the laser offsets included, not wrapped: from -0.1 to 2 pi + 0.1).
    pub azimuth: [(f32, f32); BLOCKS],
}

/// The packet's [`Extent`] as `model`; fails where [`decode_as`] fails (an unknown return
/// mode, a block azimuth above 36000).
pub fn extent<T: AsRef<[u8]>>(packet: &DataPacket<T>, model: Model) -> Result<Extent, Error> {
    let (_, gaps) = mode_and_gaps(packet, model)?;
    let channels = model.channels();
    let beams = model.beams();
    // The lasers' azimuth offsets' extremes (0 included: the block's own azimuth), and the
    // channels with a beam (the decoder skips the others).
    let (mut lo, mut hi) = (0f32, 0f32);
    let mut has_beam = [false; CHANNELS];
    for (c, has) in channels.iter().zip(has_beam.iter_mut()) {
        if let Some(beam) = beams.get(usize::from(c.laser)) {
            let o = beam.azimuth_offset_deg as f32 * (CDEG_TO_RAD * 100.0);
            (lo, hi) = (lo.min(o), hi.max(o));
            *has = true;
        }
    }
    let all = has_beam.iter().all(|&h| h);
    let mut returns = 0;
    let mut azimuth = [(0f32, 0f32); BLOCKS];
    for (b, (a, &gap)) in azimuth.iter_mut().zip(gaps.iter()).enumerate() {
        let a0 = f32::from(azimuth_cdeg(packet, b)) * CDEG_TO_RAD;
        // A firing sits a fraction (0 to 1) of the gap past its block, plus its offset.
        *a = (a0 + lo, a0 + f32::from(gap) * CDEG_TO_RAD + hi);
        returns += if all {
            packet.returns_in_block(b)
        } else {
            (0..CHANNELS)
                .filter(|&ch| has_beam[ch] && packet.distance_raw(b, ch) != 0)
                .count()
        };
    }
    Ok(Extent {
        returns: returns.min(POINTS_PER_PACKET),
        azimuth,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::rng::Rng;
    use crate::velodyne::{decode_as, BlockRepr, DataRepr, PointBuf, ReturnMode};

    /// A packet as `model` sends one: block azimuths from `start` [0.01 deg] `step` apart (in
    /// pairs in dual mode), wrapping at 36000 (sent as 36000 once), a third of the channels
    /// without a return; `step = None`: every azimuth at random (a garbled packet).
    fn packet(rng: &mut Rng, dual: bool, start: u16, step: Option<u16>) -> [u8; 1206] {
        let mut blocks = [BlockRepr {
            azimuth: 0,
            channels: [(0, 0); CHANNELS],
        }; BLOCKS];
        for (b, bl) in blocks.iter_mut().enumerate() {
            let k = if dual { b / 2 } else { b } as u32;
            bl.azimuth = match step {
                Some(s) => {
                    let a = (u32::from(start) + k * u32::from(s)) % 36_000;
                    if a == 0 && k > 0 {
                        36_000
                    } else {
                        a as u16
                    }
                }
                None => (rng.uniform() * 36_000.0) as u16,
            };
            for c in bl.channels.iter_mut() {
                if !rng.chance(0.33) {
                    *c = (rng.range(100.0, 60_000.0) as u16, 10);
                }
            }
        }
        let repr = DataRepr {
            blocks,
            timestamp_us: 1_000,
            return_mode: if dual {
                ReturnMode::Dual
            } else {
                ReturnMode::Strongest
            },
            product: 0x22,
        };
        let mut buf = [0u8; 1206];
        repr.emit(&mut DataPacket::new_unchecked(&mut buf[..]));
        buf
    }

    /// The extent holds every decoded point: the same count, and each point's azimuth (from
    /// its x and y, as the windowing sees it) inside its block's span; every model, single and
    /// dual return, across the wrap at 36000 and on garbled azimuths.
    #[test]
    fn every_decoded_point_lies_in_its_blocks_span() {
        let mut rng = Rng::new(7);
        let mut buf = PointBuf::default();
        let mut checked = 0;
        for (model, step) in [
            (Model::Vlp16, 40),
            (Model::PuckHiRes, 40),
            (Model::Hdl32e, 17),
            (Model::Vlp32c, 20),
        ] {
            for dual in [false, true] {
                for (start, step) in [
                    (0, Some(step)),
                    (17_950, Some(step)),
                    (35_800, Some(step)),
                    (35_990, Some(step)),
                    (0, None),
                ] {
                    let bytes = packet(&mut rng, dual, start, step);
                    let p = DataPacket::new_checked(&bytes[..]).unwrap();
                    let e = extent(&p, model).unwrap();
                    let n = decode_as(&p, model, &mut buf).unwrap();
                    assert_eq!(e.returns, n, "{model:?} dual {dual} start {start}");
                    for q in buf.as_slice() {
                        let (lo, hi) = e.azimuth[usize::from(q.block)];
                        let mid = 0.5 * (lo + hi);
                        let mut d = libm::atan2f(q.x, q.y) - mid;
                        while d > core::f32::consts::PI {
                            d -= core::f32::consts::TAU;
                        }
                        while d < -core::f32::consts::PI {
                            d += core::f32::consts::TAU;
                        }
                        assert!(
                            d.abs() <= 0.5 * (hi - lo) + 1e-4,
                            "{model:?} dual {dual} block {}: {d} off the middle of {lo}..{hi}",
                            q.block
                        );
                        checked += 1;
                    }
                }
            }
        }
        assert!(checked > 5_000, "{checked}");
    }

    /// Fails as the decoder does: a block azimuth above 36000.
    #[test]
    fn a_bad_azimuth_fails_as_decoding_does() {
        let mut rng = Rng::new(1);
        let mut bytes = packet(&mut rng, false, 100, Some(40));
        DataPacket::new_unchecked(&mut bytes[..]).set_azimuth_raw(3, 36_001);
        let p = DataPacket::new_unchecked(&bytes[..]);
        let mut buf = PointBuf::default();
        assert_eq!(
            extent(&p, Model::Vlp16).err(),
            decode_as(&p, Model::Vlp16, &mut buf).err()
        );
        assert!(extent(&p, Model::Vlp16).is_err());
    }
}
