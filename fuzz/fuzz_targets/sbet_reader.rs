//! Any bytes as an SBET file, and as an smrmsg file: the reader ends (end, or why it is not
//! one) without a panic; every record it returns is finite, in range and later than the one
//! before (a week rollover aside); its counts add up to the bytes given.
#![no_main]

use libfuzzer_sys::fuzz_target;
use spherecal_hal::sbet::{PospacReader, PospacRecord, SbetError, SbetRecord, SmrmsgRecord};

/// Read `data` as records of kind `T`, checking each with `each`; the reader's counts add up.
fn check<T: PospacRecord>(data: &[u8], mut each: impl FnMut(&T)) {
    let mut rd = PospacReader::<_, T>::new(data);
    let mut last: Option<f64> = None;
    let mut returned = 0u64;
    let finished = loop {
        match rd.next_record() {
            Ok(Some(r)) => {
                assert!(r.is_valid());
                let t = r.tow_s();
                if let Some(l) = last {
                    assert!(t > l || (l > 600_000.0 && t < 4_800.0));
                }
                last = Some(t);
                each(&r);
                returned += 1;
            }
            Ok(None) => break None,
            Err(e) => {
                let _ = e.to_string();
                break Some(e);
            }
        }
    };
    // A record out of time order is counted read, neither returned nor invalid.
    let out_of_order = u64::from(matches!(finished, Some(SbetError::TimeOrder { .. })));
    assert_eq!(returned + rd.invalid + out_of_order, rd.records);
    if finished.is_none() {
        assert_eq!(rd.records as usize * T::LEN + rd.trailing, data.len());
        assert!(rd.invalid * 10 <= rd.records);
    }
}

fuzz_target!(|data: &[u8]| {
    check::<SbetRecord>(data, |r| {
        let _ = r.time(2300);
        let _ = r.time(u16::MAX);
        assert!(r.heading().is_finite());
    });
    check::<SmrmsgRecord>(data, |r| {
        assert!(r.position_sigma_m().is_finite() && r.position_sigma_m() >= 0.0);
        assert!(r.attitude_sigma_rad().is_finite() && r.attitude_sigma_rad() >= 0.0);
    });
});
