//! Errors shared by every stage: a configuration that cannot work is refused once, at construction.

use thiserror::Error;

/// A configuration value that makes no sense, named by its dotted path (e.g. `detector.fov_deg`).
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum ConfigError {
    /// A field holds a value outside its valid range.
    #[error("invalid config `{field}`: {reason}")]
    Invalid {
        /// Dotted path of the field, the same name the config file and `--set` use.
        field: String,
        /// What is wrong and what would be valid.
        reason: String,
    },
}

impl ConfigError {
    /// Shorthand for [`ConfigError::Invalid`].
    pub fn invalid(field: impl Into<String>, reason: impl Into<String>) -> Self {
        Self::Invalid { field: field.into(), reason: reason.into() }
    }
}

/// Checks that `value` is finite and inside `[min, max]`, naming `field` in the error otherwise.
pub fn check_range(field: &str, value: f64, min: f64, max: f64) -> Result<(), ConfigError> {
    if !value.is_finite() || value < min || value > max {
        return Err(ConfigError::invalid(field, format!("{value} is not in [{min}, {max}]")));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn range_check_names_the_field() {
        assert!(check_range("a.b", 1.0, 0.0, 2.0).is_ok());
        let err = check_range("detector.range_m", f64::NAN, 0.0, 2.0).unwrap_err();
        assert!(err.to_string().contains("detector.range_m"));
        assert!(check_range("x", -1.0, 0.0, 2.0).is_err());
    }
}
