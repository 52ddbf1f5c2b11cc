//! `spherecal ins` as a user runs it: summary, the CSV against the independent decoding.

use crate::common;

fn tmp(name: &str) -> std::path::PathBuf {
    common::tmp("cli-ins", name)
}

/// Every expected column is in our CSV with the same value (parsed, round-trip exact).
fn csv_matches(file: &str, expected: &str) {
    let csv = tmp(&format!("{}.csv", file.replace('/', "_")));
    common::stdout_of(
        common::spherecal()
            .arg("ins")
            .arg(common::test_data(file))
            .arg("--csv")
            .arg(&csv),
    );
    let ours = std::fs::read_to_string(&csv).unwrap();
    let want = std::fs::read_to_string(common::test_data(expected)).unwrap();
    let (oh, orows) = split(&ours);
    let (wh, wrows) = split(&want);
    assert_eq!(orows.len(), wrows.len());
    assert_eq!(&oh[..3], ["offset", "header", "len"]);
    // Same columns (the expected file also has `hex`).
    let wcols: Vec<&str> = wh.iter().filter(|c| **c != "hex").copied().collect();
    assert_eq!(oh, wcols);
    for (o, w) in orows.iter().zip(&wrows) {
        for (ci, name) in oh.iter().enumerate() {
            let wi = wh.iter().position(|c| c == name).unwrap();
            let (a, b) = (o[ci], w[wi]);
            let equal = a == b
                || match (a.parse::<f64>(), b.parse::<f64>()) {
                    // Same f64; or an f32 column, which we print as the shortest f32 decimal:
                    // both must read back to the same f32.
                    (Ok(x), Ok(y)) => {
                        x == y || ((x as f32) == (y as f32) && format!("{:?}", x as f32) == a)
                    }
                    _ => false,
                };
            assert!(
                equal,
                "{file} offset {}: {name}: ours {a}, expected {b}",
                o[0]
            );
        }
    }
}

fn split(text: &str) -> (Vec<&str>, Vec<Vec<&str>>) {
    let mut l = text.lines();
    let h = l.next().unwrap().split(',').collect();
    (h, l.map(|r| r.split(',').collect()).collect())
}

#[test]
fn ins_csv_vn310_gnss() {
    csv_matches("vn200/vn310_gnss.bin", "vn200/vn310_gnss.expected.csv");
}

#[test]
fn ins_csv_vn100_logger() {
    csv_matches("vn200/vn100_F00294.raw", "vn200/vn100_F00294.expected.csv");
}

#[test]
fn ins_summary_counts() {
    let out = common::spherecal()
        .arg("ins")
        .arg(common::test_data("vn200/vn100_F00294.raw"))
        .output()
        .unwrap();
    assert!(out.status.success());
    let s = String::from_utf8(out.stdout).unwrap();
    assert!(s.contains("binary frames: 99"), "{s}");
    assert!(s.contains("header 143e003a00: 99"), "{s}");
    assert!(s.contains("CRC failures: 0"), "{s}");
    assert!(s.contains("GPRMC: 11") && s.contains("GPGGA: 10"), "{s}");
}

#[test]
fn ins_missing_file_exits_2() {
    let out = common::spherecal()
        .args(["ins", "/nonexistent/ins.bin"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("/nonexistent/ins.bin"));
}

#[test]
fn ins_counts_crc_failures() {
    let mut bytes = std::fs::read(common::test_data("vn200/vn310_imu.bin")).unwrap();
    bytes[191 + 50] ^= 0x10; // inside the second frame
    let p = tmp("corrupt.bin");
    std::fs::write(&p, &bytes).unwrap();
    let out = common::spherecal().arg("ins").arg(&p).output().unwrap();
    let s = String::from_utf8(out.stdout).unwrap();
    assert!(s.contains("binary frames: 17"), "{s}");
    assert!(s.contains("CRC failures: 1"), "{s}");
    assert!(
        s.contains("first rejected item at byte 191: CRC mismatch"),
        "{s}"
    );
}

/// A LiDAR capture or bytes from another device given to `ins`: exit 2, saying what they are
/// (not exit 0 with thousands of CRC failures).
#[test]
fn ins_refuses_a_capture_and_foreign_bytes() {
    let run = |p: &std::path::Path| {
        let out = common::spherecal().arg("ins").arg(p).output().unwrap();
        (
            out.status.code(),
            String::from_utf8_lossy(&out.stderr).to_string(),
        )
    };
    let (code, said) = run(&common::test_data("vlp16/mrpt_vlp16_gps.pcap"));
    assert_eq!(code, Some(2), "{said}");
    assert!(
        said.contains("a pcap capture, not a VN-200 byte stream"),
        "{said}"
    );
    // Bytes with VN-200 sync bytes but no valid frame (a xorshift stream, 0xFA every 97).
    let mut x = 0x2545_f491_4f6c_dd1du64;
    let bytes: Vec<u8> = (0..100_000)
        .map(|i| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            if i % 97 == 0 {
                0xFA
            } else {
                x as u8
            }
        })
        .collect();
    let p = tmp("foreign.bin");
    std::fs::write(&p, &bytes).unwrap();
    let (code, said) = run(&p);
    assert_eq!(code, Some(2), "{said}");
    assert!(said.contains("every one failing its CRC"), "{said}");
}
