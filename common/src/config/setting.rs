//! One declaration per config field. [`settings!`] takes each field's name, type, default,
//! accepted values ([`Domain`]), unit, [`Tier`] and doc lines once, and makes from them the
//! struct, its `Default`, the range checks with the field's dotted path
//! ([`Setting::check`]), and the rows of the field reference ([`Setting::rows`]) that
//! `lavatube check-config --explain` and docs/CONFIG.md print.

use super::ConfigError;
use super::range::{count_in, in_range};
use serde::de::{DeserializeOwned, Visitor};
use serde::{Deserializer, Serialize};
use std::collections::BTreeMap;
use std::fmt;
use std::marker::PhantomData;
use std::path::PathBuf;

/// Who a field is for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Tier {
    /// What most runs set: how many envs, which policy acts, how long, which files.
    Essential,
    /// Tuning of the learner, physics and processes, changed knowingly.
    Advanced,
    /// Switches for experiments on the method: the paper's interpretations and extensions.
    Research,
}

impl Tier {
    pub fn name(self) -> &'static str {
        match self {
            Tier::Essential => "essential",
            Tier::Advanced => "advanced",
            Tier::Research => "research",
        }
    }
}

/// The values a field accepts beyond what its type already rules out.
#[derive(Debug, Clone, PartialEq)]
pub enum Domain {
    /// A finite real number in `[lo, hi]`.
    Real(f64, f64),
    /// A whole number in `[lo, hi]`.
    Count(u64, u64),
    /// One of these names.
    Choices(Vec<&'static str>),
    /// Any value of the field's form, which the text names (a file path, a table).
    Form(&'static str),
}

impl fmt::Display for Domain {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Domain::Real(lo, hi) => write!(f, "[{lo}, {hi}]"),
            Domain::Count(lo, u64::MAX) => write!(f, "{lo} or more"),
            Domain::Count(lo, hi) => write!(f, "{lo} ..= {hi}"),
            Domain::Choices(names) => {
                let quoted: Vec<_> = names.iter().map(|n| format!("`{n}`")).collect();
                write!(f, "{}", quoted.join(", "))
            }
            Domain::Form(text) => f.write_str(text),
        }
    }
}

/// A real number in `[lo, hi]`.
pub fn real(lo: f64, hi: f64) -> Domain {
    Domain::Real(lo, hi)
}

/// A whole number in `[lo, hi]`.
pub fn count(lo: u64, hi: u64) -> Domain {
    Domain::Count(lo, hi)
}

/// `true` or `false`.
pub fn flag() -> Domain {
    Domain::Choices(vec!["true", "false"])
}

/// Any value of the form `text` names.
pub fn form(text: &'static str) -> Domain {
    Domain::Form(text)
}

/// The names serde accepts for the enum `T`, read from its own `Deserialize`.
pub fn choices<T: DeserializeOwned>() -> Domain {
    match T::deserialize(VariantProbe) {
        Err(Probe(Some(names))) => Domain::Choices(names.to_vec()),
        _ => panic!("{} is not an enum serde names", std::any::type_name::<T>()),
    }
}

/// One row of the field reference.
#[derive(Debug, Clone, PartialEq)]
pub struct Row {
    /// The dotted path, kebab-case (`ppo.clip-coef`); `[]` marks a list's items.
    pub key: String,
    /// The default as TOML, `required` where the field has none, `none` for an unset option.
    pub default: String,
    pub domain: Domain,
    /// The unit, empty where the value has none.
    pub unit: &'static str,
    pub tier: Tier,
    /// The doc comment's lines.
    pub doc: &'static [&'static str],
}

impl Row {
    /// The doc comment as one paragraph.
    pub fn text(&self) -> String {
        self.doc
            .iter()
            .map(|l| l.trim())
            .collect::<Vec<_>>()
            .join(" ")
    }
}

/// A config value: checks itself against its field's domain and, for a section, lists its
/// fields' rows.
pub trait Setting {
    /// Checks the value; `key` is its dotted path, for the error.
    fn check(&self, _key: &str, _domain: &Domain) -> Result<(), ConfigError> {
        Ok(())
    }

    /// A section pushes its fields' rows with this value's defaults and says true; a plain
    /// value says false, and its field's own row stands.
    fn rows(&self, _key: &str, _out: &mut Vec<Row>) -> bool {
        false
    }

    /// As [`Setting::rows`], from the type's declared defaults (a section with no value here:
    /// an unset option, a list's items).
    fn declared_rows(_key: &str, _out: &mut Vec<Row>) -> bool
    where
        Self: Sized,
    {
        false
    }
}

/// The dotted path of `field` (a Rust name) under `parent`.
pub fn key(parent: &str, field: &str) -> String {
    let kebab = field.replace('_', "-");
    if parent.is_empty() {
        kebab
    } else {
        format!("{parent}.{kebab}")
    }
}

/// A value as TOML, inline; `none` for what TOML cannot hold (an unset option).
pub fn render<T: Serialize + ?Sized>(value: &T) -> String {
    toml::Value::try_from(value).map_or_else(|_| "none".to_owned(), |v| v.to_string())
}

fn mismatch(key: &str, domain: &Domain) -> ! {
    panic!("config field `{key}` is declared with {domain:?}, which its type cannot take")
}

impl Setting for f64 {
    fn check(&self, key: &str, domain: &Domain) -> Result<(), ConfigError> {
        match *domain {
            Domain::Real(lo, hi) => in_range(key, *self, lo, hi),
            ref other => mismatch(key, other),
        }
    }
}

impl Setting for u64 {
    fn check(&self, key: &str, domain: &Domain) -> Result<(), ConfigError> {
        match *domain {
            Domain::Count(lo, hi) => count_in(key, *self, lo, hi),
            ref other => mismatch(key, other),
        }
    }
}

impl Setting for u32 {
    fn check(&self, key: &str, domain: &Domain) -> Result<(), ConfigError> {
        u64::from(*self).check(key, domain)
    }
}

impl Setting for usize {
    fn check(&self, key: &str, domain: &Domain) -> Result<(), ConfigError> {
        u64::try_from(*self).unwrap_or(u64::MAX).check(key, domain)
    }
}

impl Setting for bool {}
impl Setting for String {}
impl Setting for PathBuf {}

/// A marker of a generic section; it holds no setting.
impl<S> Setting for PhantomData<S> {
    fn rows(&self, _key: &str, _out: &mut Vec<Row>) -> bool {
        true
    }

    fn declared_rows(_key: &str, _out: &mut Vec<Row>) -> bool {
        true
    }
}

impl<T: Setting> Setting for Option<T> {
    fn check(&self, key: &str, domain: &Domain) -> Result<(), ConfigError> {
        self.as_ref().map_or(Ok(()), |v| v.check(key, domain))
    }

    fn rows(&self, key: &str, out: &mut Vec<Row>) -> bool {
        match self {
            Some(v) => v.rows(key, out),
            None => T::declared_rows(key, out),
        }
    }

    fn declared_rows(key: &str, out: &mut Vec<Row>) -> bool {
        T::declared_rows(key, out)
    }
}

impl<T: Setting> Setting for Vec<T> {
    fn check(&self, key: &str, domain: &Domain) -> Result<(), ConfigError> {
        self.iter().try_for_each(|v| v.check(key, domain))
    }

    /// A list of sections lists its items' fields under `key[]`, and keeps its own row too:
    /// the list's default is a value of its own (SPEC S1's two areas).
    fn rows(&self, key: &str, out: &mut Vec<Row>) -> bool {
        T::declared_rows(&format!("{key}[]"), out);
        false
    }

    fn declared_rows(key: &str, out: &mut Vec<Row>) -> bool {
        T::declared_rows(&format!("{key}[]"), out)
    }
}

impl<T: Setting, const N: usize> Setting for [T; N] {
    fn check(&self, key: &str, domain: &Domain) -> Result<(), ConfigError> {
        self.iter().try_for_each(|v| v.check(key, domain))
    }
}

/// A value out of its domain names its entry: `for sand, must be in [1, 10000]`.
impl<K: Serialize, V: Setting> Setting for BTreeMap<K, V> {
    fn check(&self, key: &str, domain: &Domain) -> Result<(), ConfigError> {
        self.iter().try_for_each(|(k, v)| {
            v.check(key, domain).map_err(|e| match e {
                ConfigError::Invalid {
                    field,
                    value,
                    reason,
                } => {
                    let entry = match toml::Value::try_from(k) {
                        Ok(toml::Value::String(name)) => name,
                        _ => render(k),
                    };
                    ConfigError::Invalid {
                        field,
                        value,
                        reason: format!("for {entry}, {reason}"),
                    }
                }
                other => other,
            })
        })
    }
}

/// Declares a config section: a struct whose every field is written once, as
///
/// ```text
/// /// Doc line(s).
/// pub name: Type = default => domain, "unit", Tier;
/// ```
///
/// `#[derive(Copy)]` (or other derives) after the struct's doc lines adds to the derives the
/// macro writes. A field that is itself a section leaves out `=> domain, "unit", Tier`. The struct gets
/// serde's kebab-case names with unknown keys refused. `pub struct Name { … }` fills missing
/// keys from the declared defaults; `pub struct Name, required { … }` makes a field without
/// a default required, and a field with one takes it through its own `#[serde(default)]`
/// attribute, written beside it.
macro_rules! settings {
    (
        $(#[doc = $sdoc:literal])*
        $(#[derive($($extra:ident),*)])?
        pub struct $name:ident {
            $(
                $(#[doc = $doc:literal])*
                pub $field:ident: $ty:ty = $default:expr $(=> $domain:expr, $unit:literal, $tier:ident)?;
            )*
        }
    ) => {
        $(#[doc = $sdoc])*
        #[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize $($(, $extra)*)?)]
        #[serde(deny_unknown_fields, rename_all = "kebab-case", default)]
        pub struct $name {
            $($(#[doc = $doc])* pub $field: $ty,)*
        }

        impl Default for $name {
            fn default() -> Self {
                Self { $($field: $default,)* }
            }
        }

        $crate::config::setting::settings!(@impl [] $name {
            $([$($doc)*] $field: $ty [$default] [$($domain, $unit, $tier)?];)*
        });
    };
    (
        $(#[doc = $sdoc:literal])*
        $(#[derive($($extra:ident),*)])?
        $(#[serde($($sserde:tt)*)])*
        pub struct $name:ident $(<$g:ident>)?, required {
            $(
                $(#[doc = $doc:literal])*
                $(#[serde($($serde:tt)*)])*
                pub $field:ident: $ty:ty $(= $default:expr)? $(=> $domain:expr, $unit:literal, $tier:ident)?;
            )*
        }
    ) => {
        $(#[doc = $sdoc])*
        #[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize $($(, $extra)*)?)]
        #[serde(deny_unknown_fields, rename_all = "kebab-case")]
        $(#[serde($($sserde)*)])*
        pub struct $name $(<$g>)? {
            $($(#[doc = $doc])* $(#[serde($($serde)*)])* pub $field: $ty,)*
        }

        $crate::config::setting::settings!(@impl [$($g)?] $name {
            $([$($doc)*] $field: $ty [$($default)?] [$($domain, $unit, $tier)?];)*
        });
    };
    (@impl [$($g:ident)?] $name:ident {
        $([$($doc:literal)*] $field:ident: $ty:ty [$($default:expr)?] [$($domain:expr, $unit:literal, $tier:ident)?];)*
    }) => {
        impl $(<$g>)? $crate::config::setting::Setting for $name $(<$g>)? {
            fn check(
                &self,
                parent: &str,
                _: &$crate::config::setting::Domain,
            ) -> Result<(), $crate::config::ConfigError> {
                $(
                    $crate::config::setting::Setting::check(
                        &self.$field,
                        &$crate::config::setting::key(parent, stringify!($field)),
                        &$crate::config::setting::settings!(@domain $($domain)?),
                    )?;
                )*
                Ok(())
            }

            fn rows(&self, parent: &str, out: &mut Vec<$crate::config::setting::Row>) -> bool {
                $({
                    let key = $crate::config::setting::key(parent, stringify!($field));
                    if !$crate::config::setting::Setting::rows(&self.$field, &key, out) {
                        out.push($crate::config::setting::settings!(@row key,
                            $crate::config::setting::render(&self.$field),
                            [$($domain, $unit, $tier)?] [$($doc)*]));
                    }
                })*
                true
            }

            fn declared_rows(parent: &str, out: &mut Vec<$crate::config::setting::Row>) -> bool {
                $({
                    let key = $crate::config::setting::key(parent, stringify!($field));
                    if !<$ty as $crate::config::setting::Setting>::declared_rows(&key, out) {
                        out.push($crate::config::setting::settings!(@row key,
                            $crate::config::setting::settings!(@default $ty $(, $default)?),
                            [$($domain, $unit, $tier)?] [$($doc)*]));
                    }
                })*
                true
            }
        }
    };
    (@row $key:ident, $default:expr, [$($domain:expr, $unit:literal, $tier:ident)?] [$($doc:literal)*]) => {
        $crate::config::setting::Row {
            default: $default,
            key: $key,
            domain: $crate::config::setting::settings!(@domain $($domain)?),
            unit: $crate::config::setting::settings!(@unit $($unit)?),
            tier: $crate::config::setting::settings!(@tier $($tier)?),
            doc: &[$($doc),*],
        }
    };
    (@domain) => { $crate::config::setting::Domain::Form("a section") };
    (@domain $domain:expr) => { $domain };
    (@unit) => { "" };
    (@unit $unit:literal) => { $unit };
    (@tier) => { $crate::config::setting::Tier::Advanced };
    (@tier $tier:ident) => { $crate::config::setting::Tier::$tier };
    (@default $ty:ty) => { "required".to_owned() };
    (@default $ty:ty, $default:expr) => { $crate::config::setting::render::<$ty>(&$default) };
}
pub(crate) use settings;

/// Reads the variant names a serde enum accepts: a deserializer that asks for an enum and
/// keeps the names it is shown.
struct VariantProbe;

#[derive(Debug)]
struct Probe(Option<&'static [&'static str]>);

impl fmt::Display for Probe {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("not an enum")
    }
}

impl std::error::Error for Probe {}

impl serde::de::Error for Probe {
    fn custom<T: fmt::Display>(_: T) -> Self {
        Probe(None)
    }
}

impl<'de> Deserializer<'de> for VariantProbe {
    type Error = Probe;

    fn deserialize_any<V: Visitor<'de>>(self, _: V) -> Result<V::Value, Probe> {
        Err(Probe(None))
    }

    fn deserialize_enum<V: Visitor<'de>>(
        self,
        _: &'static str,
        variants: &'static [&'static str],
        _: V,
    ) -> Result<V::Value, Probe> {
        Err(Probe(Some(variants)))
    }

    serde::forward_to_deserialize_any! {
        bool i8 i16 i32 i64 i128 u8 u16 u32 u64 u128 f32 f64 char str string bytes byte_buf
        option unit unit_struct newtype_struct seq tuple tuple_struct map struct identifier
        ignored_any
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, serde::Deserialize)]
    #[serde(rename_all = "kebab-case")]
    enum Engine {
        Fused,
        BurnAutodiff,
    }

    #[test]
    fn choices_are_the_names_serde_accepts() {
        assert_eq!(
            choices::<Engine>(),
            Domain::Choices(vec!["fused", "burn-autodiff"])
        );
        let _ = (Engine::Fused, Engine::BurnAutodiff);
    }

    #[test]
    fn keys_are_dotted_kebab_paths() {
        assert_eq!(key("", "ppo"), "ppo");
        assert_eq!(key("ppo", "clip_coef"), "ppo.clip-coef");
    }

    #[test]
    fn values_render_as_toml() {
        assert_eq!(render(&0.2), "0.2");
        assert_eq!(render(&vec![128usize, 128]), "[128, 128]");
        assert_eq!(render(&None::<f64>), "none");
        assert_eq!(render("fused"), "\"fused\"");
    }

    #[test]
    fn checks_follow_the_domain() {
        let e = 1.5f64.check("a.x", &real(0.0, 1.0)).expect_err("above");
        assert_eq!(e.to_string(), "config field `a.x` = 1.5: must be in [0, 1]");
        assert!(f64::NAN.check("a.x", &real(0.0, 1.0)).is_err());
        assert!(Some(3usize).check("a.n", &count(1, 2)).is_err());
        assert!(None::<usize>.check("a.n", &count(1, 2)).is_ok());
        assert!(vec![1u32, 5].check("a.n", &count(1, 4)).is_err());
        assert!([0.5, 0.25].check("a.x", &real(0.0, 1.0)).is_ok());
    }
}
