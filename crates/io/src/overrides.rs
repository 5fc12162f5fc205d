//! Dotted-key overrides of any configuration (`mpc.horizon_steps = 30`): the one implementation
//! behind the command line's `--set key=value` and the ROS 2 node's parameters.
//!
//! An override goes through the TOML form of the configuration, so every key a config file accepts
//! can be set and an unknown key is refused by name (croprow's configs deny unknown fields). A
//! section that is absent because it is optional (`faults.dropout`) is created. Validating the result
//! stays the caller's job: the configuration's own `validate` knows its ranges.
//!
//! ```
//! use croprow_core::NavigatorConfig;
//! use croprow_io::overrides;
//! let nav = NavigatorConfig::default();
//! let nav = overrides::set(&nav, "mpc.horizon_steps", toml::Value::Integer(30)).unwrap();
//! assert_eq!(nav.mpc.horizon_steps, 30);
//! let e = overrides::set(&nav, "mpc.horizon", toml::Value::Integer(3)).unwrap_err();
//! assert!(e.to_string().contains("mpc.horizon"));
//! ```

use croprow_core::ConfigError;
use serde::Serialize;
use serde::de::DeserializeOwned;

/// Returns `config` with the leaf at the dotted `key` set to `value`. An integer is accepted for a
/// float leaf; any other type mismatch, an unknown key, a key naming a section, or a value the
/// configuration refuses is an error naming `key`. `config` itself is never changed.
pub fn set<T: Serialize + DeserializeOwned>(
    config: &T,
    key: &str,
    value: toml::Value,
) -> Result<T, ConfigError> {
    let mut tree = tree_of(config, key)?;
    let (last, parents) = parts(key)?;
    let mut node = &mut tree;
    for part in parents {
        let toml::Value::Table(table) = node else {
            return Err(ConfigError::invalid(key, format!("`{part}` is inside a value, not a section")));
        };
        node = table.entry(part).or_insert_with(|| toml::Value::Table(toml::Table::new()));
    }
    let toml::Value::Table(table) = node else {
        return Err(ConfigError::invalid(key, "is inside a value, not a section"));
    };
    let value = match (table.get(last), value) {
        (Some(toml::Value::Table(_)), _) => {
            return Err(ConfigError::invalid(key, "is a section, not a value"));
        }
        (Some(toml::Value::Float(_)), toml::Value::Integer(i)) => toml::Value::Float(i as f64),
        (Some(current), v) if current.type_str() != v.type_str() => {
            return Err(ConfigError::invalid(
                key,
                format!("expects a {}, got a {}", current.type_str(), v.type_str()),
            ));
        }
        (_, v) => v,
    };
    table.insert(last.to_owned(), value);
    tree.try_into().map_err(|e: toml::de::Error| ConfigError::invalid(key, e.message()))
}

/// The current value of the leaf at the dotted `key`; an error naming `key` when there is no such
/// leaf or it is a section.
pub fn leaf<T: Serialize>(config: &T, key: &str) -> Result<toml::Value, ConfigError> {
    let tree = tree_of(config, key)?;
    let mut node = &tree;
    for part in key.split('.') {
        node = node.get(part).ok_or_else(|| ConfigError::invalid(key, "no such setting"))?;
    }
    if node.is_table() {
        return Err(ConfigError::invalid(key, "is a section, not a value"));
    }
    Ok(node.clone())
}

/// Parses `text` as a value of the same type as `current` (`"5"` for a float leaf is 5.0, `"paper"`
/// for a string leaf is the string): how text-only sources (ROS 2 string parameters, a terminal)
/// set typed leaves.
pub fn parse_as(current: &toml::Value, key: &str, text: &str) -> Result<toml::Value, ConfigError> {
    let bad = |what: &str| ConfigError::invalid(key, format!("`{text}` is not {what}"));
    Ok(match current {
        toml::Value::Integer(_) => toml::Value::Integer(text.trim().parse().map_err(|_| bad("an integer"))?),
        toml::Value::Float(_) => toml::Value::Float(text.trim().parse().map_err(|_| bad("a number"))?),
        toml::Value::Boolean(_) => {
            toml::Value::Boolean(text.trim().parse().map_err(|_| bad("true or false"))?)
        }
        toml::Value::String(_) => toml::Value::String(text.to_owned()),
        _ => return Err(ConfigError::invalid(key, "is a section, not a value")),
    })
}

/// Splits one `--set key=value` item at its first `=` into the dotted key and the value's text,
/// both trimmed; an item without `=` is an error that quotes it.
pub fn split_assignment(item: &str) -> Result<(&str, &str), ConfigError> {
    let (key, text) = item.split_once('=').ok_or_else(|| ConfigError::invalid(item, "expected KEY=VALUE"))?;
    Ok((key.trim(), text.trim()))
}

/// Parses the text after `=` in `--set key=value` as a TOML value; a bare word is a string
/// (`detector.mode=paper`), so nobody has to quote inside a shell.
pub fn parse_literal(text: &str) -> toml::Value {
    toml::from_str::<toml::Table>(&format!("v = {text}"))
        .ok()
        .and_then(|mut t| t.remove("v"))
        .unwrap_or_else(|| toml::Value::String(text.to_owned()))
}

fn tree_of<T: Serialize>(config: &T, key: &str) -> Result<toml::Value, ConfigError> {
    toml::Value::try_from(config).map_err(|e| ConfigError::invalid(key, e.to_string()))
}

/// Splits `a.b.c` into the leaf `c` and its sections `[a, b]`; empty parts are refused.
fn parts(key: &str) -> Result<(&str, Vec<&str>), ConfigError> {
    let all: Vec<&str> = key.split('.').map(str::trim).collect();
    if all.iter().any(|p| p.is_empty()) {
        return Err(ConfigError::invalid(key, "is not a dotted name like `mpc.horizon_steps`"));
    }
    let (last, parents) = all.split_last().ok_or_else(|| ConfigError::invalid(key, "empty key"))?;
    Ok((last, parents.to_vec()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde::Deserialize;

    #[derive(Debug, PartialEq, Serialize, Deserialize, Default)]
    #[serde(default, deny_unknown_fields)]
    struct Inner {
        rate_hz: f64,
        steps: u32,
        name: String,
    }

    #[derive(Debug, PartialEq, Serialize, Deserialize, Default)]
    #[serde(default, deny_unknown_fields)]
    struct Outer {
        inner: Inner,
        optional: Option<Inner>,
    }

    #[test]
    fn sets_a_nested_leaf_and_accepts_an_integer_for_a_float() {
        let c = set(&Outer::default(), "inner.rate_hz", toml::Value::Integer(10)).unwrap();
        assert_eq!(c.inner.rate_hz, 10.0);
        let c = set(&c, "inner.name", parse_literal("paper")).unwrap();
        assert_eq!(c.inner.name, "paper");
    }

    #[test]
    fn creates_an_absent_optional_section() {
        let c = set(&Outer::default(), "optional.steps", toml::Value::Integer(3)).unwrap();
        assert_eq!(c.optional.map(|o| o.steps), Some(3));
    }

    #[test]
    fn refuses_by_name_unknown_keys_sections_wrong_types_and_bad_names() {
        let c = Outer::default();
        for (key, value) in [
            ("inner.nope", toml::Value::Integer(1)),
            ("inner", toml::Value::Integer(1)),
            ("inner.steps", toml::Value::Float(1.5)),
            ("inner.steps.deeper", toml::Value::Integer(1)),
            ("inner..steps", toml::Value::Integer(1)),
            ("", toml::Value::Integer(1)),
        ] {
            let e = set(&c, key, value).unwrap_err();
            assert!(e.to_string().contains(key), "{key}: {e}");
        }
    }

    #[test]
    fn a_leaf_is_read_and_text_is_parsed_as_its_type() {
        let c = Outer::default();
        let current = leaf(&c, "inner.rate_hz").unwrap();
        assert_eq!(parse_as(&current, "inner.rate_hz", "5").unwrap(), toml::Value::Float(5.0));
        assert!(parse_as(&current, "inner.rate_hz", "fast").is_err());
        assert!(leaf(&c, "inner").is_err());
        assert!(leaf(&c, "inner.nope").is_err());
    }

    #[test]
    fn an_assignment_splits_at_its_first_equals_sign() {
        assert_eq!(split_assignment(" mpc.horizon_steps = 30 ").unwrap(), ("mpc.horizon_steps", "30"));
        assert_eq!(split_assignment("topic=/a=b").unwrap(), ("topic", "/a=b"));
        let e = split_assignment("mpc.horizon_steps").unwrap_err();
        assert!(e.to_string().contains("mpc.horizon_steps"), "{e}");
    }

    #[test]
    fn a_literal_is_toml_and_a_bare_word_a_string() {
        assert_eq!(parse_literal("30"), toml::Value::Integer(30));
        assert_eq!(parse_literal("\"paper\""), toml::Value::String("paper".into()));
        assert_eq!(parse_literal("paper"), toml::Value::String("paper".into()));
    }
}
