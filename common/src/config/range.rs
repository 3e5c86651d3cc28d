//! The checks behind every documented range, public so that other config files (the bench's)
//! word their errors exactly as the run config does.

use super::ConfigError;
use std::fmt::{Debug, Display};

/// The error for `field` holding `value`, with why it is refused.
pub fn invalid(field: &str, value: impl Debug, reason: impl Into<String>) -> ConfigError {
    ConfigError::Invalid {
        field: field.to_owned(),
        value: format!("{value:?}"),
        reason: reason.into(),
    }
}

/// Checks `lo <= value <= hi` (and finiteness) for one field.
pub fn in_range(field: &str, value: f64, lo: f64, hi: f64) -> Result<(), ConfigError> {
    if value.is_finite() && (lo..=hi).contains(&value) {
        Ok(())
    } else {
        Err(invalid(field, value, format!("must be in [{lo}, {hi}]")))
    }
}

/// Checks `lo <= value <= hi` for a count (any integer type).
pub fn count_in<T>(field: &str, value: T, lo: T, hi: T) -> Result<(), ConfigError>
where
    T: Copy + PartialOrd + Debug + Display,
{
    if (lo..=hi).contains(&value) {
        Ok(())
    } else {
        Err(invalid(field, value, format!("must be in [{lo}, {hi}]")))
    }
}

/// Checks a list of counts: non-empty, each in `lo ..= hi`, no value twice.
pub fn count_list<T>(field: &str, values: &[T], lo: T, hi: T) -> Result<(), ConfigError>
where
    T: Copy + Ord + Debug + Display,
{
    if values.is_empty() {
        return Err(invalid(field, values, "needs at least one value"));
    }
    if let Some(bad) = values.iter().find(|v| !(lo..=hi).contains(*v)) {
        return Err(invalid(
            field,
            values,
            format!("{bad} is not in [{lo}, {hi}]"),
        ));
    }
    let mut sorted = values.to_vec();
    sorted.sort_unstable();
    sorted.dedup();
    if sorted.len() != values.len() {
        return Err(invalid(field, values, "lists a value twice"));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_and_lists_name_the_field_and_the_range() {
        let e = count_in("a.n", 11u64, 1, 10).expect_err("too many");
        assert_eq!(e.to_string(), "config field `a.n` = 11: must be in [1, 10]");
        assert!(count_in("a.n", 10usize, 1, 10).is_ok());
        assert!(count_list("a.list", &[1usize, 4], 1, 4).is_ok());
        let e = count_list::<usize>("a.list", &[], 1, 4).expect_err("empty");
        assert_eq!(
            e.to_string(),
            "config field `a.list` = []: needs at least one value"
        );
        let e = count_list("a.list", &[1usize, 5], 1, 4).expect_err("range");
        assert_eq!(
            e.to_string(),
            "config field `a.list` = [1, 5]: 5 is not in [1, 4]"
        );
        let e = count_list("a.list", &[2usize, 2], 1, 4).expect_err("twice");
        assert_eq!(
            e.to_string(),
            "config field `a.list` = [2, 2]: lists a value twice"
        );
    }
}
