//! Why a diagnosis could not run.

/// Why a diagnosis could not run.
#[derive(Clone, Debug, PartialEq)]
pub enum DiagnoseError {
    /// The user's model cannot be simulated on the recording.
    Model(String),
    /// The split leaves no fit rows or no held-out rows.
    Split(String),
    /// A plot of the report could not be drawn.
    Plot(String),
    /// An option is out of its range (the option and why).
    Option(String),
    /// A fit did not move from its start though it could have: no estimate to report.
    NotFitted(String),
}

impl std::fmt::Display for DiagnoseError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            DiagnoseError::Model(m) => write!(f, "{m}"),
            DiagnoseError::Split(m) => write!(f, "{m}"),
            DiagnoseError::Plot(m) => write!(f, "{m}"),
            DiagnoseError::Option(m) => write!(f, "{m}"),
            DiagnoseError::NotFitted(m) => write!(f, "{m}"),
        }
    }
}

impl std::error::Error for DiagnoseError {}
