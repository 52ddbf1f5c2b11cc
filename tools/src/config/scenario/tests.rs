use super::*;

#[test]
fn builtins_parse() {
    for (name, _) in BUILTIN {
        let s = Scenario::load(name).unwrap();
        assert_eq!(&s.name, name);
        assert!(s.duration_s() <= 120.0, "{name}: {} s", s.duration_s());
    }
}

#[test]
fn unknown_keys_and_bad_values_are_named() {
    let text = BUILTIN[0].1;
    let e = Scenario::from_toml(&text.replace("rpm = 600", "rpm = 600\nrmp = 3")).unwrap_err();
    assert!(e.0.contains("unknown field `rmp`"), "{e}");
    let e = Scenario::from_toml(&text.replace("rpm = 600", "rpm = 5000")).unwrap_err();
    assert_eq!(e.0, "lidar.rpm: expected 300..=1200");
    let e = Scenario::from_toml(&text.replace("radius_m = 0.19", "radius_m = -1")).unwrap_err();
    assert_eq!(e.0, "sphere[0].radius_m: expected 0 < r < 5");
    let e =
        Scenario::from_toml(&text.replace("return_mode = \"strongest\"", "return_mode = \"both\""))
            .unwrap_err();
    assert_eq!(e.0, "lidar.return_mode: expected strongest, last or dual");
}

/// TOML reads `inf` and `nan`: every non-finite value is refused with its key.
#[test]
fn non_finite_values_are_named() {
    let text = BUILTIN[0].1;
    for (from, to, key) in [
        ("radius_m = 0.19", "radius_m = inf", "sphere[0].radius_m"),
        ("radius_m = 0.19", "radius_m = nan", "sphere[0].radius_m"),
        (
            "ins_down_m = 0.0",
            "ins_down_m = nan",
            "trajectory.ins_down_m",
        ),
        (
            "range_sigma_m = 0.0",
            "range_sigma_m = nan",
            "lidar.range_sigma_m",
        ),
        (
            "time_offset_s = 0.0",
            "time_offset_s = inf",
            "ins.time_offset_s",
        ),
        ("duration_s = 20.0", "duration_s = inf", "trajectory"),
        (
            "window_margin_m = 3.0",
            "window_margin_m = nan",
            "mount.apriori.window_margin_m",
        ),
        (
            "reflectivity = 0.45",
            "reflectivity = nan",
            "box[1].reflectivity",
        ),
        (
            "size_m = [40.0, 8.0, 6.0]",
            "size_m = [40.0, inf, 6.0]",
            "box[1].size_m",
        ),
    ] {
        assert!(text.contains(from), "{from}");
        let e = Scenario::from_toml(&text.replacen(from, to, 1)).unwrap_err();
        assert!(e.0.starts_with(&format!("{key}: ")), "{to}: {e}");
    }
}

#[test]
fn utc_parsing() {
    // 2016-01-21T08:18:02Z = 16821 days + 8 h 18 min 2 s.
    assert_eq!(
        parse_utc("2016-01-21T08:18:02Z"),
        Some((16_821 * 86_400 + 8 * 3600 + 18 * 60 + 2) * 1_000_000_000)
    );
    assert_eq!(parse_utc("2016-01-21 08:18:02"), None);
    assert_eq!(parse_utc("2016-13-21T08:18:02Z"), None);
}

/// `[ins.correlated]`: a preset reaches the simulator's INS settings in its units; a bad table
/// is refused naming its key.
#[test]
fn correlated_ins_errors_from_the_table() {
    let text = BUILTIN[0].1.replace(
        "[trajectory]",
        "[ins.correlated]\npreset = \"posmv-rtk\"\ncorrelation_s = 15\n\n[trajectory]",
    );
    let s = Scenario::from_toml(&text).unwrap();
    let c = s.ins_config().correlated;
    assert_eq!((c.position_sigma, c.correlation_s), ([0.03, 0.06], 15.0));
    assert!((c.attitude_sigma[0] - 0.01f64.to_radians()).abs() < 1e-15);
    assert!(!Scenario::load("table1")
        .unwrap()
        .ins_config()
        .correlated
        .is_on());
    let e = Scenario::from_toml(&text.replace("posmv-rtk", "posmv")).unwrap_err();
    assert!(e.0.starts_with("ins.correlated.preset: \"posmv\""), "{e}");
    let e =
        Scenario::from_toml(&text.replace("correlation_s = 15", "correlation_s = -1")).unwrap_err();
    assert!(e.0.starts_with("ins.correlated.correlation_s"), "{e}");
    let e = Scenario::from_toml(&text.replace("correlation_s = 15", "sigma = 1")).unwrap_err();
    assert!(e.0.contains("unknown field `sigma`"), "{e}");
}
