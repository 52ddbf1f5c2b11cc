//! Where the repository's real test data is.

use std::path::PathBuf;

/// A file under the repository's `tests/data` (real captures; origins and licences in its
/// README). Fails the test loudly when it is missing: these tests must never skip silently.
pub fn test_data(rel: &str) -> PathBuf {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../tests/data")
        .join(rel);
    assert!(p.exists(), "missing test data {}", p.display());
    p
}
