//! The tools' error: a message for people and a kind that decides the exit code of the
//! command contract (DESIGN.md "Commands"; embedded-io's `ErrorKind` pattern). Every library
//! function of the tools returns it; a plain message converts with `?` or `.into()` as bad
//! input. Only clap's value parsers, `FromStr` and the rig's check list keep `String`.

use std::fmt;
use std::process::ExitCode;

/// What kind of failure.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ErrorKind {
    /// Unreadable, inconsistent or missing input, a bad argument, an output that cannot be
    /// written: exit 2.
    BadInput,
    /// The inputs were read but no result can be claimed from them: exit 1.
    Refused,
    /// A fault of spherecal itself (a worker thread that panicked): exit 4, please report.
    Internal,
}

impl ErrorKind {
    /// The exit code (0 is success).
    pub fn exit_code(self) -> u8 {
        match self {
            ErrorKind::Refused => 1,
            ErrorKind::BadInput => 2,
            ErrorKind::Internal => 4,
        }
    }
}

/// A failure: its kind and what to tell the user.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Error {
    kind: ErrorKind,
    message: String,
}

impl Error {
    /// An error of `kind`.
    pub fn new(kind: ErrorKind, message: impl Into<String>) -> Self {
        Self {
            kind,
            message: message.into(),
        }
    }
    /// Bad input.
    pub fn bad_input(message: impl Into<String>) -> Self {
        Self::new(ErrorKind::BadInput, message)
    }
    /// Internal: `what` failed in spherecal itself.
    pub fn internal(what: impl fmt::Display) -> Self {
        Self::new(
            ErrorKind::Internal,
            format!("internal error: {what} (a fault of spherecal: please report it)"),
        )
    }
    /// Its kind.
    pub fn kind(&self) -> ErrorKind {
        self.kind
    }
    /// The exit code of the command contract.
    pub fn exit_code(&self) -> ExitCode {
        ExitCode::from(self.kind.exit_code())
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.message)
    }
}

impl std::error::Error for Error {}

/// A plain message is bad input (what every `Err(String)` of the tools meant).
impl From<String> for Error {
    fn from(message: String) -> Self {
        Self::bad_input(message)
    }
}

impl From<&str> for Error {
    fn from(message: &str) -> Self {
        Self::bad_input(message)
    }
}

/// The message alone (for lists of messages; the kind is lost there).
impl From<Error> for String {
    fn from(e: Error) -> Self {
        e.message
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kinds_map_to_the_contract_and_messages_survive() {
        let e: Error = "no such file".to_string().into();
        assert_eq!((e.kind(), e.kind().exit_code()), (ErrorKind::BadInput, 2));
        assert_eq!(Error::new(ErrorKind::Refused, "x").kind().exit_code(), 1);
        let i = Error::internal("the LiDAR reader panicked");
        assert_eq!(i.kind().exit_code(), 4);
        assert!(i
            .to_string()
            .starts_with("internal error: the LiDAR reader panicked"));
        assert_eq!(String::from(Error::bad_input("m")), "m");
    }
}
