//! Typed, located reading of a parsed TOML table: every value keeps its span, every unknown
//! key is reported with the nearest valid one, every number is checked finite and in range.

use super::color;
use super::error::Diagnostic;
use super::params::{self, Range};
use glam::{DVec3, Vec3};
use std::cell::RefCell;
use toml::Spanned;
use toml::de::{DeTable, DeValue};

/// Collects the diagnostics of one scene file.
pub(crate) struct Sink<'s> {
    pub file: &'s str,
    pub src: &'s str,
    diags: RefCell<Vec<Diagnostic>>,
}

impl<'s> Sink<'s> {
    pub fn new(file: &'s str, src: &'s str) -> Self {
        Sink {
            file,
            src,
            diags: RefCell::new(Vec::new()),
        }
    }

    pub fn error(
        &self,
        span: std::ops::Range<usize>,
        key: String,
        message: String,
        help: Option<String>,
    ) {
        let d = Diagnostic::at(self.file, self.src, span, key, message, help);
        self.diags.borrow_mut().push(d);
    }

    pub fn into_diagnostics(self) -> Vec<Diagnostic> {
        let mut d = self.diags.into_inner();
        d.sort_by_key(|d| (d.line, d.column));
        d
    }
}

/// The valid key nearest to `key`, when one is close enough to be a likely typo.
pub(crate) fn suggest<'k>(key: &str, valid: &[&'k str]) -> Option<&'k str> {
    valid
        .iter()
        .map(|v| (strsim::jaro_winkler(key, v), *v))
        .filter(|(score, _)| *score > 0.8)
        .max_by(|a, b| a.0.total_cmp(&b.0))
        .map(|(_, v)| v)
}

/// One TOML table being read: `ctx` says where it is (`[camera]`, `[[sphere]] #2`).
pub(crate) struct Table<'a, 's> {
    sink: &'a Sink<'s>,
    table: &'a DeTable<'s>,
    span: std::ops::Range<usize>,
    ctx: String,
}

impl<'a, 's> Table<'a, 's> {
    /// Wraps `table`, reporting at once every key that is not in `allowed`.
    pub fn new(
        sink: &'a Sink<'s>,
        table: &'a DeTable<'s>,
        span: std::ops::Range<usize>,
        ctx: String,
        allowed: &[&str],
    ) -> Self {
        let t = Table {
            sink,
            table,
            span,
            ctx,
        };
        for (k, _) in t.table.iter() {
            let name: &str = k.get_ref();
            if !allowed.contains(&name) {
                let help = match suggest(name, allowed) {
                    Some(s) => format!("did you mean `{s}`?"),
                    None => format!("valid keys here: {}", allowed.join(", ")),
                };
                t.sink.error(
                    k.span(),
                    t.ctx.clone(),
                    format!("unknown key `{name}`"),
                    Some(help),
                );
            }
        }
        t
    }

    fn label(&self, key: &str) -> String {
        format!("{} key `{key}`", self.ctx)
    }

    fn get(&self, key: &str) -> Option<&'a Spanned<DeValue<'s>>> {
        self.table.get(key)
    }

    pub fn has(&self, key: &str) -> bool {
        self.get(key).is_some()
    }

    /// Span of a key's value, or of the table when the key is absent.
    pub fn span_of(&self, key: &str) -> std::ops::Range<usize> {
        self.get(key).map_or(self.span.clone(), |v| v.span())
    }

    /// Reports a problem with `key` (or with the table when the key is absent).
    pub fn error(&self, key: &str, message: impl Into<String>, help: Option<String>) {
        self.sink
            .error(self.span_of(key), self.label(key), message.into(), help);
    }

    /// Reports a problem with the table as a whole.
    pub fn error_table(&self, message: impl Into<String>, help: Option<String>) {
        self.sink
            .error(self.span.clone(), self.ctx.clone(), message.into(), help);
    }

    fn type_error(&self, key: &str, v: &Spanned<DeValue<'s>>, expected: &str) {
        self.sink.error(
            v.span(),
            self.label(key),
            format!("expected {expected}, found {}", v.get_ref().type_str()),
            None,
        );
    }

    /// A number from a value, reporting non-numbers, NaN and infinities.
    fn number(&self, key: &str, v: &Spanned<DeValue<'s>>) -> Option<f64> {
        let x = match v.get_ref() {
            DeValue::Integer(i) => i64::from_str_radix(&i.as_str().replace('_', ""), i.radix())
                .ok()
                .map(|x| x as f64),
            DeValue::Float(f) => f.as_str().replace('_', "").parse::<f64>().ok(),
            _ => {
                self.type_error(key, v, "a number");
                return None;
            }
        };
        match x {
            Some(x) if x.is_finite() => Some(x),
            _ => {
                self.sink.error(
                    v.span(),
                    self.label(key),
                    format!("must be a finite number, found `{}`", raw(v)),
                    None,
                );
                None
            }
        }
    }

    /// Any finite number.
    pub fn f64(&self, key: &str) -> Option<f64> {
        let v = self.get(key)?;
        self.number(key, v)
    }

    /// A finite number in `[lo, hi]`.
    pub fn f64_in(&self, key: &str, lo: f64, hi: f64) -> Option<f64> {
        self.f64_range(key, &Range::closed(lo, hi), "")
    }

    /// A finite number greater than `lo`.
    pub fn f64_above(&self, key: &str, lo: f64) -> Option<f64> {
        self.f64_range(key, &Range::above(lo), "")
    }

    /// A finite number in `range` (`unit` follows the range in the error's help).
    fn f64_range(&self, key: &str, range: &Range, unit: &str) -> Option<f64> {
        let v = self.get(key)?;
        let x = self.number(key, v)?;
        if !range.contains(x) {
            let unit = if unit.is_empty() {
                String::new()
            } else {
                format!(" {unit}")
            };
            self.sink.error(
                v.span(),
                self.label(key),
                format!("{x} is out of range"),
                Some(format!("`{key}` must be {}{unit}", range.describe())),
            );
            return None;
        }
        Some(x)
    }

    /// The value of the parameter that `[table] key` sets (`params`), checked against its
    /// declared range (a whole number where it counts).
    pub fn param(&self, table: &str, key: &str) -> Option<f64> {
        let s = params::for_toml(table, key).spec();
        if s.step == params::Step::Count {
            return self
                .u32_in(key, s.range.lo as u32, s.range.hi as u32)
                .map(f64::from);
        }
        let unit = if s.unit == "degrees" { s.unit } else { "" };
        self.f64_range(key, &s.range, unit)
    }

    /// An integer in `[lo, hi]`.
    pub fn u32_in(&self, key: &str, lo: u32, hi: u32) -> Option<u32> {
        let v = self.get(key)?;
        let DeValue::Integer(i) = v.get_ref() else {
            self.type_error(key, v, "an integer");
            return None;
        };
        let x = i64::from_str_radix(&i.as_str().replace('_', ""), i.radix()).ok();
        match x {
            Some(x) if x >= lo as i64 && x <= hi as i64 => Some(x as u32),
            _ => {
                self.sink.error(
                    v.span(),
                    self.label(key),
                    format!("{} is out of range", raw(v)),
                    Some(format!("`{key}` must be an integer from {lo} to {hi}")),
                );
                None
            }
        }
    }

    /// Three finite numbers `[x, y, z]`.
    pub fn vec3(&self, key: &str) -> Option<DVec3> {
        let v = self.get(key)?;
        let Some(arr) = v.get_ref().as_array() else {
            self.type_error(key, v, "an array of three numbers like [0, 1, 0]");
            return None;
        };
        if arr.len() != 3 {
            self.sink.error(
                v.span(),
                self.label(key),
                format!("expected three numbers [x, y, z], found {}", arr.len()),
                None,
            );
            return None;
        }
        let mut out = [0.0; 3];
        for (o, e) in out.iter_mut().zip(arr.iter()) {
            *o = self.number(key, e)?;
        }
        Some(DVec3::from_array(out))
    }

    /// A scale: one number for all axes, or `[x, y, z]`.
    pub fn scale(&self, key: &str) -> Option<DVec3> {
        let v = self.get(key)?;
        if v.get_ref().is_array() {
            self.vec3(key)
        } else {
            self.number(key, v).map(DVec3::splat)
        }
    }

    /// A colour: `"#rrggbb"` (sRGB, decoded to linear) or a linear `[r, g, b]`, each ≥ 0.
    pub fn color(&self, key: &str) -> Option<Vec3> {
        let v = self.get(key)?;
        if let Some(s) = v.get_ref().as_str() {
            return match color::parse_hex(s) {
                Some(c) => Some(c),
                None => {
                    self.sink.error(
                        v.span(),
                        self.label(key),
                        format!("`{s}` is not a colour"),
                        Some("write \"#rrggbb\" (sRGB) or [r, g, b] (linear)".into()),
                    );
                    None
                }
            };
        }
        if !v.get_ref().is_array() {
            self.type_error(key, v, "a colour \"#rrggbb\" or [r, g, b]");
            return None;
        }
        let c = self.vec3(key)?;
        if c.min_element() < 0.0 {
            self.sink.error(
                v.span(),
                self.label(key),
                "colour components must be ≥ 0".into(),
                None,
            );
            return None;
        }
        Some(c.as_vec3())
    }

    /// `true` or `false`.
    pub fn boolean(&self, key: &str) -> Option<bool> {
        let v = self.get(key)?;
        match v.get_ref().as_bool() {
            Some(b) => Some(b),
            None => {
                self.type_error(key, v, "true or false");
                None
            }
        }
    }

    /// A string.
    pub fn string(&self, key: &str) -> Option<String> {
        let v = self.get(key)?;
        match v.get_ref().as_str() {
            Some(s) => Some(s.to_string()),
            None => {
                self.type_error(key, v, "a string");
                None
            }
        }
    }

    /// A sub-table (`[render]`, or inline `sun = { ... }`).
    pub fn table(&self, key: &str, ctx: String, allowed: &[&str]) -> Option<Table<'a, 's>> {
        let v = self.get(key)?;
        match v.get_ref().as_table() {
            Some(t) => Some(Table::new(self.sink, t, v.span(), ctx, allowed)),
            None => {
                self.type_error(key, v, "a table");
                None
            }
        }
    }

    /// Every entry of a table of tables (`[materials.NAME]`), with its key.
    pub fn named_tables(&self, key: &str, allowed: &[&str]) -> Vec<(String, Table<'a, 's>)> {
        let Some(v) = self.get(key) else {
            return Vec::new();
        };
        let Some(t) = v.get_ref().as_table() else {
            self.type_error(key, v, "a table of named tables");
            return Vec::new();
        };
        let mut out = Vec::new();
        for (k, v) in t.iter() {
            let name = k.get_ref().to_string();
            match v.get_ref().as_table() {
                Some(inner) => out.push((
                    name.clone(),
                    Table::new(
                        self.sink,
                        inner,
                        k.span(),
                        format!("[{key}.{name}]"),
                        allowed,
                    ),
                )),
                None => self.type_error(&name, v, "a table"),
            }
        }
        out
    }

    /// Every table of an array of tables (`[[sphere]]`), numbered from 1 in messages.
    pub fn array_of_tables(&self, key: &str, allowed: &[&str]) -> Vec<Table<'a, 's>> {
        let Some(v) = self.get(key) else {
            return Vec::new();
        };
        let Some(arr) = v.get_ref().as_array() else {
            self.type_error(key, v, &format!("tables written [[{key}]]"));
            return Vec::new();
        };
        let mut out = Vec::new();
        for (i, e) in arr.iter().enumerate() {
            match e.get_ref().as_table() {
                Some(t) => out.push(Table::new(
                    self.sink,
                    t,
                    e.span(),
                    format!("[[{key}]] #{}", i + 1),
                    allowed,
                )),
                None => self.type_error(key, e, "a table"),
            }
        }
        out
    }
}

/// The source text of a value, for messages.
fn raw(v: &Spanned<DeValue<'_>>) -> String {
    match v.get_ref() {
        DeValue::Integer(i) => i.as_str().to_string(),
        DeValue::Float(f) => f.as_str().to_string(),
        other => other.type_str().to_string(),
    }
}
