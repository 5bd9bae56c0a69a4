//! Reading plain YAML documents (Kalibr, ROS) field by field, so that every
//! error names the field and says what was expected.

use std::borrow::Cow;

use serde::Deserialize;
use serde_norway::{Mapping, Value};

use crate::error::{CalibError, FieldError, Result};

/// The text with OpenCV's `%YAML:1.0` line blanked (line numbers stay as
/// they are), and whether it had one. OpenCV writes that line first in
/// every YAML file, and some other tools copy it (Kalibr camchains from
/// some pipelines begin with it); YAML parsers refuse it, since YAML's own
/// directive is `%YAML 1.1` or `%YAML 1.2`, which they accept.
pub(crate) fn without_opencv_directive(text: &str) -> (Cow<'_, str>, bool) {
    let body = text.trim_start_matches('\u{feff}');
    if !body.starts_with("%YAML:") {
        return (Cow::Borrowed(text), false);
    }
    let rest = body.find('\n').map_or("", |i| &body[i..]);
    (Cow::Owned(rest.to_owned()), true)
}

/// Parses YAML text into a document; `file` names it in errors. OpenCV's
/// `%YAML:1.0` line is passed over, and so are empty documents (a `---`
/// after the document, as `ros2 topic echo` prints it); more than one
/// document is an error.
pub(crate) fn parse(text: &str, file: &str) -> Result<Value> {
    let parse_error = |detail: String| CalibError::Parse {
        file: file.into(),
        detail,
    };
    let (text, _) = without_opencv_directive(text);
    let mut docs = Vec::new();
    for doc in serde_norway::Deserializer::from_str(&text) {
        let v = Value::deserialize(doc).map_err(|e| parse_error(e.to_string()))?;
        if !v.is_null() {
            docs.push(v);
        }
    }
    match docs.len() {
        0 => Ok(Value::Null),
        1 => Ok(docs.swap_remove(0)),
        n => Err(parse_error(format!(
            "{n} YAML documents (separated by ---); expected one"
        ))),
    }
}

/// A short description of a value, for "found …".
pub(crate) fn describe(v: &Value) -> String {
    match v {
        Value::Null => "nothing".into(),
        Value::Bool(b) => format!("the boolean {b}"),
        Value::Number(n) => format!("the number {n}"),
        Value::String(s) => format!("the string \"{s}\""),
        Value::Sequence(s) => format!("a list of {} items", s.len()),
        Value::Mapping(_) => "a map".into(),
        Value::Tagged(t) => format!("a value tagged {}", t.tag),
    }
}

/// A map of a document, with the path of fields leading to it.
pub(crate) struct Map<'a> {
    pub map: &'a Mapping,
    pub path: String,
    pub file: &'a str,
}

impl<'a> Map<'a> {
    /// The top-level map of a document.
    pub fn root(v: &'a Value, file: &'a str, expected: &str) -> Result<Self> {
        match v {
            Value::Mapping(map) => Ok(Self {
                map,
                path: String::new(),
                file,
            }),
            other => Err(FieldError::new("(document)", expected, describe(other)).in_file(file)),
        }
    }

    pub fn field_name(&self, key: &str) -> String {
        if self.path.is_empty() {
            key.to_owned()
        } else {
            format!("{}.{key}", self.path)
        }
    }

    pub fn error(&self, key: &str, expected: &str, found: impl Into<String>) -> CalibError {
        FieldError::new(self.field_name(key), expected, found).in_file(self.file)
    }

    pub fn get(&self, key: &str) -> Option<&'a Value> {
        self.map.get(key).filter(|v| !v.is_null())
    }

    pub fn require(&self, key: &str, expected: &str) -> Result<&'a Value> {
        self.get(key).ok_or_else(|| CalibError::Missing {
            file: self.file.into(),
            field: self.field_name(key),
            expected: expected.into(),
        })
    }

    pub fn map(&self, key: &str, expected: &str) -> Result<Map<'a>> {
        match self.require(key, expected)? {
            Value::Mapping(map) => Ok(Map {
                map,
                path: self.field_name(key),
                file: self.file,
            }),
            other => Err(self.error(key, expected, describe(other))),
        }
    }

    pub fn string(&self, key: &str, expected: &str) -> Result<&'a str> {
        match self.require(key, expected)? {
            Value::String(s) => Ok(s),
            other => Err(self.error(key, expected, describe(other))),
        }
    }

    /// A positive whole number (of pixels, rows, columns).
    pub fn pixels(&self, key: &str) -> Result<u32> {
        let expected = "a positive whole number";
        let v = self.require(key, expected)?;
        match v.as_u64() {
            Some(x) if (1..=1_000_000).contains(&x) => Ok(x as u32),
            _ => Err(self.error(key, expected, describe(v))),
        }
    }

    /// A finite number.
    pub fn number(&self, key: &str, expected: &str) -> Result<f64> {
        let v = self.require(key, expected)?;
        v.as_f64()
            .filter(|x| x.is_finite())
            .ok_or_else(|| self.error(key, expected, describe(v)))
    }

    /// A list of finite numbers; `len` checks its length.
    pub fn numbers(&self, key: &str, len: Option<usize>, expected: &str) -> Result<Vec<f64>> {
        numbers_of(self.require(key, expected)?, len)
            .map_err(|found| self.error(key, expected, found))
    }
}

/// The numbers of a list value, or a description of what it is instead.
pub(crate) fn numbers_of(v: &Value, len: Option<usize>) -> std::result::Result<Vec<f64>, String> {
    let Value::Sequence(items) = v else {
        return Err(describe(v));
    };
    if let Some(n) = len {
        if items.len() != n {
            return Err(format!("{} numbers", items.len()));
        }
    }
    items
        .iter()
        .enumerate()
        .map(|(i, x)| match x.as_f64() {
            Some(f) if f.is_finite() => Ok(f),
            _ => Err(format!("item {i}: {}", describe(x))),
        })
        .collect()
}

/// Writes a YAML document.
pub(crate) fn to_string<T: serde::Serialize>(v: &T) -> Result<String> {
    serde_norway::to_string(v).map_err(|e| CalibError::Argument(format!("cannot write YAML: {e}")))
}
