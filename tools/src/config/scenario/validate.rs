//! A scenario's validation: unknown keys are refused by serde, impossible values here, each
//! named by its key (`config::checks`).

use super::*;
use crate::config::checks::{check, finite};

impl Scenario {
    /// Reject impossible values, naming the key.
    pub fn validate(&self) -> Result<(), ScenarioError> {
        self.validate_site_and_spheres()?;
        self.validate_mount()?;
        self.validate_lidar()?;
        self.validate_scene()?;
        self.validate_ins()?;
        self.validate_trajectory()?;
        Ok(())
    }

    /// The site and the spheres.
    fn validate_site_and_spheres(&self) -> Result<(), ScenarioError> {
        check(
            parse_utc(&self.start_utc).is_some(),
            "start_utc",
            "expected YYYY-MM-DDTHH:MM:SSZ",
        )?;
        check(
            (0..=100).contains(&self.leap_seconds),
            "leap_seconds",
            "expected 0..=100",
        )?;
        check(
            self.site.lat_deg.abs() <= 90.0 && finite(&[self.site.lat_deg]),
            "site.lat_deg",
            "expected -90..=90",
        )?;
        check(
            self.site.lon_deg.abs() <= 180.0 && finite(&[self.site.lon_deg]),
            "site.lon_deg",
            "expected -180..=180",
        )?;
        check(
            finite(&[self.site.h_m]) && self.site.h_m.abs() < 1e4,
            "site.h_m",
            "expected a finite height under 10 km",
        )?;
        check(!self.sphere.is_empty(), "sphere", "at least one sphere")?;
        check(
            self.sphere.len() <= spherecal::sim::lidar::MAX_TARGETS,
            "sphere",
            "at most 16 spheres",
        )?;
        for (i, sp) in self.sphere.iter().enumerate() {
            check(
                sp.radius_m > 0.0 && sp.radius_m < 5.0,
                &format!("sphere[{i}].radius_m"),
                "expected 0 < r < 5",
            )?;
            check(
                finite(&sp.ned_m),
                &format!("sphere[{i}].ned_m"),
                "not finite",
            )?;
            check(
                Stand::parse(&sp.stand).is_some(),
                &format!("sphere[{i}].stand"),
                "expected none, pole or tripod",
            )?;
            check(
                sp.stand_down_m
                    .is_none_or(|f| f.is_finite() && f > sp.ned_m[2] + sp.radius_m + 0.3),
                &format!("sphere[{i}].stand_down_m"),
                "expected a floor at least 0.3 m below the sphere",
            )?;
            check(
                sp.reflectivity > 0.0 && sp.reflectivity <= 1.0,
                &format!("sphere[{i}].reflectivity"),
                "expected 0 < rho <= 1",
            )?;
        }
        Ok(())
    }

    /// The true and a-priori mountings.
    fn validate_mount(&self) -> Result<(), ScenarioError> {
        let t = &self.mount.truth;
        check(
            finite(&t.boresight_deg) && finite(&t.lever_arm_m),
            "mount.truth",
            "not finite",
        )?;
        check(
            t.lever_arm_m.iter().all(|x| x.abs() < 50.0),
            "mount.truth.lever_arm_m",
            "expected |x| < 50 m",
        )?;
        let a = &self.mount.apriori;
        check(
            finite(&a.boresight_deg) && finite(&a.lever_arm_m),
            "mount.apriori",
            "not finite",
        )?;
        check(
            a.window_margin_m > 0.0 && a.window_margin_m < 20.0,
            "mount.apriori.window_margin_m",
            "expected 0 < m < 20",
        )?;
        Ok(())
    }

    /// The LiDAR model.
    fn validate_lidar(&self) -> Result<(), ScenarioError> {
        check(
            self.scanner().is_some(),
            "lidar.model",
            "expected vlp16, puck-hires, hdl32e, vlp32c, xt16, xt32, os0-128, os1-64, os1-128 or os2-128",
        )?;
        // An Ouster runs 512, 1024 or 2048 columns a frame at 10,240 columns a second, one
        // return a column in the profile simulated.
        if let Some(spherecal::sim::Scanner::Ouster(_)) = self.scanner() {
            check(
                [300.0, 600.0, 1200.0].contains(&self.lidar.rpm),
                "lidar.rpm",
                "an Ouster turns at 300, 600 or 1200 rpm (its 2048x5, 1024x10 and 512x20 modes)",
            )?;
            check(
                self.lidar.return_mode == "strongest",
                "lidar.return_mode",
                "an Ouster's single-return profile (RNG19_RFL8_SIG16_NIR16) reports the strongest",
            )?;
        }
        check(
            (300.0..=1200.0).contains(&self.lidar.rpm),
            "lidar.rpm",
            "expected 300..=1200",
        )?;
        check(
            self.return_mode().is_some(),
            "lidar.return_mode",
            "expected strongest, last or dual",
        )?;
        check(
            self.lidar.range_sigma_m >= 0.0 && self.lidar.range_sigma_m < 1.0,
            "lidar.range_sigma_m",
            "expected 0..1 m",
        )?;
        check(
            (0.0..=1.0).contains(&self.lidar.drop_prob),
            "lidar.drop_prob",
            "expected 0..=1",
        )?;
        check(
            self.lidar
                .beam_divergence_mrad
                .iter()
                .all(|x| (0.0..50.0).contains(x)),
            "lidar.beam_divergence_mrad",
            "expected 0..50 mrad",
        )?;
        check(
            self.lidar.merge_distance_m >= 0.0 && self.lidar.merge_distance_m < 20.0,
            "lidar.merge_distance_m",
            "expected 0..20 m",
        )?;
        check(
            self.lidar.clock_offset_s.abs() < 3600.0,
            "lidar.clock_offset_s",
            "expected |offset| < 3600 s",
        )?;
        check(
            self.lidar.clock_drift_ppm.abs() <= 1000.0,
            "lidar.clock_drift_ppm",
            "expected |drift| <= 1000 ppm",
        )?;
        check(
            self.pps().is_some(),
            "lidar.pps",
            "expected locked, absent, syncing or error",
        )?;
        check(
            self.lidar.clutter_keep > 0.0 && self.lidar.clutter_keep <= 1.0,
            "lidar.clutter_keep",
            "expected 0 < p <= 1",
        )?;
        check(
            self.lidar.range_walk_m.abs() < 1.0,
            "lidar.range_walk_m",
            "expected |walk| < 1 m",
        )?;
        check(
            self.lidar.intensity_gain > 0.0 && self.lidar.intensity_gain <= 100.0,
            "lidar.intensity_gain",
            "expected 0 < gain <= 100",
        )?;
        check(
            (0.0..=2.0).contains(&self.lidar.intensity_scatter),
            "lidar.intensity_scatter",
            "expected 0..2 (the sigma of a log-normal factor)",
        )?;
        check(
            (0.0..=1.0).contains(&self.lidar.edge_dropout),
            "lidar.edge_dropout",
            "expected a probability 0..1",
        )?;
        Ok(())
    }

    /// The scenery (its objects counted with the spheres and stands).
    fn validate_scene(&self) -> Result<(), ScenarioError> {
        let spec = self.scene_spec();
        spec.validate()?;
        check(
            self.sphere.len() * 6 + spec.max_objects() <= spherecal::sim::lidar::MAX_OBJECTS,
            "scatter",
            "too many objects: at most 1024 in a scene (spheres and stands included)",
        )?;
        Ok(())
    }

    /// The INS model.
    fn validate_ins(&self) -> Result<(), ScenarioError> {
        check(
            self.ins.rate_hz >= 1.0 && self.ins.rate_hz <= 1000.0,
            "ins.rate_hz",
            "expected 1..=1000",
        )?;
        check(
            self.ins.att_sigma_deg >= 0.0 && self.ins.att_sigma_deg < 10.0,
            "ins.att_sigma_deg",
            "expected 0..10",
        )?;
        check(
            self.ins.pos_sigma_m >= 0.0 && self.ins.pos_sigma_m < 10.0,
            "ins.pos_sigma_m",
            "expected 0..10",
        )?;
        self.ins
            .correlated
            .resolve("ins.correlated")
            .map_err(|e| ScenarioError(e.into()))?;
        check(
            self.ins.time_offset_s.abs() < 10.0,
            "ins.time_offset_s",
            "expected |t| < 10 s",
        )?;
        check(
            matches!(self.ins.kind.as_str(), "vn200" | "posmv"),
            "ins.kind",
            "expected vn200 or posmv",
        )?;
        check(
            (0.0..=1.0).contains(&self.ins.corrupt_prob),
            "ins.corrupt_prob",
            "expected 0..=1",
        )?;
        check(
            matches!(self.ins.attitude.as_str(), "yaw_pitch_roll" | "quaternion"),
            "ins.attitude",
            "expected yaw_pitch_roll or quaternion",
        )?;
        check(
            self.ins.clock_steps.len() <= 4
                && self
                    .ins
                    .clock_steps
                    .iter()
                    .all(|[a, d]| a.is_finite() && *a >= 0.0 && d.is_finite() && d.abs() < 10.0),
            "ins.clock_steps",
            "expected at most 4 [at_s >= 0, |step_s| < 10]",
        )?;
        check(
            self.ins.position_jumps.len() <= 4
                && self.ins.position_jumps.iter().all(|[a, n, e, d]| {
                    a.is_finite() && *a >= 0.0 && [n, e, d].iter().all(|v| v.abs() < 100.0)
                }),
            "ins.position_jumps",
            "expected at most 4 [at_s >= 0, north_m, east_m, down_m], each |jump| < 100 m",
        )?;
        check(
            self.ins.outages.len() <= 4
                && self.ins.outages.iter().all(|o| {
                    o.iter().all(|v| v.is_finite())
                        && o[0] >= 0.0
                        && o[1] > 0.0
                        && o[2..5].iter().all(|v| v.abs() < 100.0)
                        && o[5..].iter().all(|v| v.abs() < 10.0)
                }),
            "ins.outages",
            "expected at most 4 [at_s >= 0, duration_s > 0, north_m, east_m, down_m, roll_deg, pitch_deg, heading_deg], each peak |position| < 100 m and |angle| < 10 deg",
        )?;
        Ok(())
    }

    /// The trajectory.
    fn validate_trajectory(&self) -> Result<(), ScenarioError> {
        let tr = &self.trajectory;
        check(
            !tr.pass.is_empty() || tr.file.is_some(),
            "trajectory.pass",
            "at least one pass (or trajectory.file)",
        )?;
        check(
            tr.turn_s >= 0.0 && tr.turn_s < 600.0,
            "trajectory.turn_s",
            "expected 0..600",
        )?;
        check(
            tr.ins_down_m.is_finite() && tr.ins_down_m.abs() < 1e4,
            "trajectory.ins_down_m",
            "expected a finite height",
        )?;
        for (k, w) in [
            ("roll", tr.roll),
            ("pitch", tr.pitch),
            ("yaw", tr.yaw),
            ("heave", tr.heave),
        ] {
            check(
                finite(&w) && w[0].abs() < 45.0 && w[1] >= 0.0,
                &format!("trajectory.{k}"),
                "expected [amplitude, period >= 0]",
            )?;
        }
        for (i, p) in tr.pass.iter().enumerate() {
            check(
                p.speed_mps > 0.0 && p.speed_mps < 50.0,
                &format!("trajectory.pass[{i}].speed_mps"),
                "expected 0 < v < 50",
            )?;
            check(
                p.duration_s > 0.0,
                &format!("trajectory.pass[{i}].duration_s"),
                "expected > 0",
            )?;
            check(
                finite(&p.start_ne_m) && p.heading_deg.is_finite(),
                &format!("trajectory.pass[{i}]"),
                "not finite",
            )?;
            check(
                p.down_m.is_none_or(|d| d.is_finite() && d.abs() < 1e4),
                &format!("trajectory.pass[{i}].down_m"),
                "expected a finite down [m], |down| < 10 km",
            )?;
        }
        check(
            self.duration_s() <= 3600.0,
            "trajectory",
            "at most an hour of scanning",
        )?;
        Ok(())
    }
}
