//! Why the model refuses its inputs.

use crate::field::config::ConfigError;

/// Errors of the model entry points; each names the offending input.
#[derive(Debug, thiserror::Error)]
pub enum ModelError {
    #[error(transparent)]
    Config(#[from] ConfigError),
    #[error("model config: `{key}` = {value} is invalid: {why}")]
    Invalid {
        key: &'static str,
        value: String,
        why: &'static str,
    },
    #[error("batch: `{what}` has {got} entries, expected {expected}")]
    Shape {
        what: &'static str,
        expected: usize,
        got: usize,
    },
    #[error("batch: ray {ray} uses appearance code {code}, but the table has {n_codes} codes")]
    CodeOutOfRange {
        ray: usize,
        code: u32,
        n_codes: usize,
    },
    #[error("batch: ray {ray} has a non-finite origin or direction")]
    NonFiniteRay { ray: usize },
    #[error("parameter buffer has {got} values, the layout needs {expected}")]
    ParamLen { expected: usize, got: usize },
}
