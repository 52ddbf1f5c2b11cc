//! What a scenario's and its scenery's validation share: the error naming the key at fault
//! and the checks that make it.

/// A scenario that cannot be used, with the key at fault.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ScenarioError(pub String);

impl std::fmt::Display for ScenarioError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for ScenarioError {}

/// A scenario that cannot be used is bad input.
impl From<ScenarioError> for crate::Error {
    fn from(e: ScenarioError) -> Self {
        Self::bad_input(e.0)
    }
}

/// `Err(key: why)` unless `ok`.
pub(crate) fn check(ok: bool, key: &str, why: &str) -> Result<(), ScenarioError> {
    if ok {
        Ok(())
    } else {
        Err(ScenarioError(format!("{key}: {why}")))
    }
}

/// Every value finite.
pub(crate) fn finite(v: &[f64]) -> bool {
    v.iter().all(|x| x.is_finite())
}
