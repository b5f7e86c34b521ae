//! The range of one of a scene's numbers, said once: a [`Range`] const per key, which its JSON
//! Schema reads (`#[schemars(transform = KEY.schema())]`, or `KEY.items()` for every item of an
//! array) and `Scene::validate` checks (`KEY.check(field, x)`), in messages written from the
//! range.

use crate::error::{Error, Result};
use schemars::Schema;

/// One end of a range: its value, and whether the value itself is outside (open).
#[derive(Debug, Clone, Copy, PartialEq)]
struct End {
    value: f64,
    open: bool,
}

/// The values a number may take: finite, between its ends (either may be absent). A range
/// open at 0 from below (`> 0`) asks for at least the smallest normal double, whose inverse is
/// finite; the schema says `exclusiveMinimum: 0`, the nearest it can.
#[derive(Debug, Clone, Copy)]
pub struct Range {
    min: Option<End>,
    max: Option<End>,
    /// What messages add in parentheses: the unit (`Pa`), what a count counts (`steps between
    /// history rows`) or a remark; empty for nothing.
    note: &'static str,
    /// What messages call the value: `number`, or its symbol (`μ`).
    symbol: &'static str,
}

impl Range {
    /// `> min`.
    pub const fn above(min: f64, note: &'static str) -> Range {
        Range {
            min: Some(End {
                value: min,
                open: true,
            }),
            max: None,
            note,
            symbol: "number",
        }
    }

    /// `≥ min`.
    pub const fn at_least(min: f64, note: &'static str) -> Range {
        Range {
            min: Some(End {
                value: min,
                open: false,
            }),
            max: None,
            note,
            symbol: "number",
        }
    }

    /// This range, and `< max`.
    pub const fn below(self, max: f64) -> Range {
        Range {
            max: Some(End {
                value: max,
                open: true,
            }),
            ..self
        }
    }

    /// This range, and `≤ max`.
    pub const fn at_most(self, max: f64) -> Range {
        Range {
            max: Some(End {
                value: max,
                open: false,
            }),
            ..self
        }
    }

    /// This range, its value called `symbol` in messages (`μ`).
    pub const fn called(self, symbol: &'static str) -> Range {
        Range { symbol, ..self }
    }

    /// The schema transform that writes the range into a number's schema.
    pub fn schema(self) -> impl FnMut(&mut Schema) {
        move |schema| self.write(schema)
    }

    /// The schema transform that writes the range into the schema of every item of an array.
    pub fn items(self) -> impl FnMut(&mut Schema) {
        move |schema| {
            if let Some(items) = schema
                .get_mut("items")
                .and_then(|i| <&mut Schema>::try_from(i).ok())
            {
                self.write(items);
            }
        }
    }

    /// The least value, for a count (`cells`, `count`) checked with its product.
    fn least(&self) -> f64 {
        self.min.map_or(f64::NEG_INFINITY, |m| m.value)
    }

    /// The largest value.
    fn most(&self) -> f64 {
        self.max.map_or(f64::INFINITY, |m| m.value)
    }

    /// Whether `x` lies in the range.
    fn holds(&self, x: f64) -> bool {
        let above = |e: End| {
            if e.open && e.value == 0.0 {
                x.is_normal() && x > 0.0
            } else if e.open {
                x > e.value
            } else {
                x >= e.value
            }
        };
        let below = |e: End| if e.open { x < e.value } else { x <= e.value };
        x.is_finite() && self.min.is_none_or(above) && self.max.is_none_or(below)
    }

    /// ` (note)`, or nothing.
    fn note(&self) -> String {
        if self.note.is_empty() {
            String::new()
        } else {
            format!(" ({})", self.note)
        }
    }

    /// Refuses a number `x` out of the range, naming its key `field`.
    ///
    /// # Errors
    /// `x` is not finite or lies outside the range; the message gives the range and `x`.
    pub fn check(&self, field: &str, x: f64) -> Result<()> {
        if self.holds(x) {
            return Ok(());
        }
        let note = self.note();
        let message = match (self.min, self.max) {
            (
                Some(End {
                    value: 0.0,
                    open: true,
                }),
                None,
            ) => format!(
                "must be a finite number > 0 (at least {:e}, the smallest normal double), got \
                 {x:e}",
                f64::MIN_POSITIVE
            ),
            (Some(lo), Some(hi)) => format!(
                "must lie in {}{}, {}{}{note}, got {x}",
                if lo.open { '(' } else { '[' },
                lo.value,
                hi.value,
                if hi.open { ')' } else { ']' },
            ),
            (Some(e), None) => format!(
                "must be a finite {} {} {}{note}, got {x}",
                self.symbol,
                if e.open { ">" } else { "≥" },
                e.value
            ),
            (None, Some(e)) => format!(
                "must be a finite {} {} {}{note}, got {x}",
                self.symbol,
                if e.open { "<" } else { "≤" },
                e.value
            ),
            (None, None) => "must be a finite number".to_string(),
        };
        Err(Error::scene(field, message))
    }

    /// Refuses a count `n` out of the range (whose ends are whole and closed), naming its key.
    ///
    /// # Errors
    /// `n` lies outside the range.
    ///
    /// # Panics
    /// Never for a range with an end: a range with none holds every count.
    pub fn check_count(&self, field: &str, n: u64) -> Result<()> {
        if self.holds(n as f64) {
            return Ok(());
        }
        let note = self.note();
        let message = match (self.min, self.max) {
            (Some(lo), Some(hi)) => {
                format!("must lie in {}..={}{note}, got {n}", lo.value, hi.value)
            }
            (Some(lo), None) => format!("must be ≥ {}{note}, got {n}", lo.value),
            (None, Some(hi)) => format!("must be ≤ {}{note}, got {n}", hi.value),
            (None, None) => unreachable!("a count holds where the range has no end"),
        };
        Err(Error::scene(field, message))
    }

    /// Refuses a pair of counts (`[nx, ny]`) either of which is below the range or whose
    /// product is above it, naming its key.
    ///
    /// # Errors
    /// A count is below the range's least value, or their product above its most.
    pub fn check_pair(&self, field: &str, pair: [usize; 2]) -> Result<()> {
        let product = pair[0].saturating_mul(pair[1]);
        if pair.iter().all(|&n| n as f64 >= self.least()) && product as f64 <= self.most() {
            return Ok(());
        }
        Err(Error::scene(
            field,
            format!(
                "both counts must be ≥ {} and their product ≤ {}, got {pair:?}",
                self.least(),
                self.most()
            ),
        ))
    }

    /// Writes the range into a number's schema.
    fn write(&self, schema: &mut Schema) {
        if let Some(e) = self.min {
            let key = if e.open {
                "exclusiveMinimum"
            } else {
                "minimum"
            };
            schema.insert(key.into(), number(e.value));
        }
        if let Some(e) = self.max {
            let key = if e.open {
                "exclusiveMaximum"
            } else {
                "maximum"
            };
            schema.insert(key.into(), number(e.value));
        }
    }
}

/// A bound as the schema writes it: whole numbers without a fraction (`0`, not `0.0`).
fn number(x: f64) -> serde_json::Value {
    if x.fract() == 0.0 && x.abs() < 9e15 {
        (x as i64).into()
    } else {
        x.into()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_check_what_they_say() {
        let nu = Range::above(-1.0, "").below(0.5);
        assert!(nu.check("nu", 0.2).is_ok());
        let e = nu.check("nu", 0.5).unwrap_err().to_string();
        assert!(e.contains("must lie in (-1, 0.5), got 0.5"), "{e}");
        let positive = Range::above(0.0, "m");
        assert!(positive.check("x", f64::MIN_POSITIVE / 2.0).is_err());
        assert!(positive.check("x", f64::INFINITY).is_err());
        let e = Range::at_least(0.0, "Pa").check("c", -1.0).unwrap_err();
        assert!(e.to_string().contains("≥ 0 (Pa), got -1"), "{e}");
        let cells = Range::at_least(1.0, "").at_most(6.0);
        assert!(cells.check_pair("c", [2, 3]).is_ok());
        assert!(cells.check_pair("c", [3, 3]).is_err());
        assert!(cells.check_pair("c", [0, 3]).is_err());
        assert!(cells.check_count("c", 7).is_err());
    }

    #[test]
    fn the_schema_says_the_same() {
        let mut schema = schemars::json_schema!({"type": "number"});
        Range::at_least(0.0, "").below(90.0).schema()(&mut schema);
        assert_eq!(
            serde_json::Value::from(schema),
            serde_json::json!({"type": "number", "minimum": 0, "exclusiveMaximum": 90})
        );
        let mut schema = schemars::json_schema!({"type": "array", "items": {"type": "number"}});
        Range::above(0.0, "m").items()(&mut schema);
        assert_eq!(schema.get("items").unwrap()["exclusiveMinimum"], 0);
    }
}
