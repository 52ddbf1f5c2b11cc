//! Makes the footprint's tables (`src/calib/footprint/table.rs`) from the quadrature the core
//! uses (`src/calib/footprint/quad.rs`, the same file, with `make.rs`): nothing to keep in
//! step by hand.

use std::io::Write;

#[path = "src/calib/footprint/make.rs"]
mod make;
#[allow(dead_code)]
#[path = "src/calib/footprint/quad.rs"]
mod quad;

fn main() {
    println!("cargo:rerun-if-changed=src/calib/footprint/quad.rs");
    println!("cargo:rerun-if-changed=src/calib/footprint/make.rs");
    println!("cargo:rerun-if-changed=build.rs");
    let out = std::path::PathBuf::from(std::env::var("OUT_DIR").expect("cargo sets OUT_DIR"));
    let mut f = std::fs::File::create(out.join("footprint_table.rs")).expect("OUT_DIR writable");
    let n = quad::NQ * quad::NW * quad::NT;
    writeln!(
        f,
        "/// kappa = 0.5: `[t][w][q]`.\npub static HALF: [f32; {n}] = ["
    )
    .unwrap();
    for it in 0..quad::NT {
        for iw in 0..quad::NW {
            for iq in 0..quad::NQ {
                write!(f, "{:?},", make::table_entry(0.5, it, iw, iq)).unwrap();
            }
            writeln!(f).unwrap();
        }
    }
    writeln!(f, "];").unwrap();
}
