//! A request's `args`, named as the command line's options and arguments are, turned into the family
//! crate's checked argument types through their `FromStr` (one rule, one message, in every front end).

use std::str::FromStr;

use serde_json::{Map, Value};

use crate::error::ErrorReport;

/// The arguments of one request, taken one by one; [`Args::finish`] refuses any left over.
#[derive(Debug)]
pub struct Args {
    op: String,
    map: Map<String, Value>,
    taken: Vec<&'static str>,
}

impl Args {
    /// The arguments `map` of the action `op`.
    pub fn new(op: &str, map: Map<String, Value>) -> Args {
        Args { op: op.to_string(), map, taken: Vec::new() }
    }

    /// The argument `key` as the text the command line would be given: a string as it is, a number or a
    /// boolean as written. `None` when it is absent (or null).
    pub fn text(&mut self, key: &'static str) -> Result<Option<String>, ErrorReport> {
        self.taken.push(key);
        match self.map.remove(key) {
            None | Some(Value::Null) => Ok(None),
            Some(Value::String(s)) => Ok(Some(s)),
            Some(Value::Number(n)) => Ok(Some(n.to_string())),
            Some(Value::Bool(b)) => Ok(Some(b.to_string())),
            Some(other) => Err(ErrorReport::usage(format!(
                "{}: {key} must be a number, a string or a boolean, not {}",
                self.op,
                crate::request::kind_of(&other)
            ))),
        }
    }

    /// The argument `key` checked by its type's rule; `None` when absent.
    pub fn get<T: FromStr>(&mut self, key: &'static str) -> Result<Option<T>, ErrorReport>
    where
        T::Err: std::fmt::Display,
    {
        match self.text(key)? {
            None => Ok(None),
            Some(text) => {
                text.parse::<T>().map(Some).map_err(|e| ErrorReport::usage(format!("{} {key} {text:?}: {e}", self.op)))
            }
        }
    }

    /// The argument `key`, which the action needs.
    pub fn need<T: FromStr>(&mut self, key: &'static str) -> Result<T, ErrorReport>
    where
        T::Err: std::fmt::Display,
    {
        self.get(key)?.ok_or_else(|| ErrorReport::usage(format!("{}: the argument {key:?} is missing", self.op)))
    }

    /// The list argument `key` (the command line's repeated argument, such as `values` of COMPAX
    /// `status`): a JSON list of values or one value, each checked by its type's rule; empty when absent (an
    /// empty list given is a mistake, refused: absent is how a request asks for the action's default).
    pub fn list<T: FromStr>(&mut self, key: &'static str) -> Result<Vec<T>, ErrorReport>
    where
        T::Err: std::fmt::Display,
    {
        let items = match self.map.remove(key) {
            Some(Value::Array(items)) if items.is_empty() => {
                return Err(ErrorReport::usage(format!("{}: {key:?} is an empty list", self.op)));
            }
            Some(Value::Array(items)) => items,
            Some(one) => vec![one],
            None => Vec::new(),
        };
        let mut all = Vec::new();
        for item in items {
            self.map.insert(key.to_string(), item);
            all.extend(self.get::<T>(key)?);
        }
        self.taken.push(key);
        self.taken.dedup();
        Ok(all)
    }

    /// The argument `one` (one value) or `many` (a list of them, the command line's repeated argument, as
    /// `get` takes several names), exactly one of the two: the texts, and whether a list was given (its
    /// result is then a list too, even of one).
    pub fn one_or_many(&mut self, one: &'static str, many: &'static str) -> Result<(Vec<String>, bool), ErrorReport> {
        let given = self.map.contains_key(many);
        let list = self.list::<String>(many)?;
        let single = self.text(one)?;
        match (single, given) {
            (Some(t), false) => Ok((vec![t], false)),
            (None, true) => Ok((list, true)),
            (Some(_), true) => Err(ErrorReport::usage(format!("{}: give {one:?} or {many:?}, not both", self.op))),
            (None, false) => {
                Err(ErrorReport::usage(format!("{}: the argument {one:?} is missing (or {many:?}, a list)", self.op)))
            }
        }
    }

    /// [`Args::one_or_many`], each text parsed by `parse` (all of them before anything is read): a text it
    /// refuses is a usage error naming it.
    pub fn one_or_many_parsed<T, E: std::fmt::Display>(
        &mut self,
        one: &'static str,
        many: &'static str,
        parse: impl Fn(&str) -> Result<T, E>,
    ) -> Result<(Vec<T>, bool), ErrorReport> {
        let (texts, list) = self.one_or_many(one, many)?;
        let parsed =
            texts.iter().map(|t| parse(t).map_err(|e| ErrorReport::usage(format!("{} {one} {t:?}: {e}", self.op))));
        Ok((parsed.collect::<Result<_, _>>()?, list))
    }

    /// A flag (`binary`, `soft`): true, false or absent (false).
    pub fn flag(&mut self, key: &'static str) -> Result<bool, ErrorReport> {
        Ok(self.get::<bool>(key)?.unwrap_or(false))
    }

    /// Refuses arguments the action does not take, naming those it takes.
    pub fn finish(self) -> Result<(), ErrorReport> {
        match self.map.keys().next() {
            None => Ok(()),
            Some(key) => {
                let takes = match self.taken.is_empty() {
                    true => "no arguments".to_string(),
                    false => self.taken.join(", "),
                };
                Err(ErrorReport::usage(format!("{}: unknown argument {key:?}; it takes {takes}", self.op)))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn args(v: Value) -> Args {
        let Value::Object(m) = v else { panic!("an object") };
        Args::new("move", m)
    }

    #[test]
    fn values_go_through_the_types_own_rules() {
        let mut a = args(serde_json::json!({"position": 300, "speed": "50", "binary": true, "x": [1]}));
        assert_eq!(a.need::<u32>("position").unwrap(), 300);
        assert_eq!(a.get::<u8>("speed").unwrap(), Some(50));
        assert!(a.flag("binary").unwrap());
        assert_eq!(a.get::<u8>("accel").unwrap(), None);
        assert!(a.text("x").unwrap_err().message.contains("not a list"));
        let mut a = args(serde_json::json!({"values": ["S1", "S17"], "one": 2, "bad": [1, [2]]}));
        assert_eq!(a.list::<String>("values").unwrap(), ["S1", "S17"]);
        assert_eq!(a.list::<u8>("one").unwrap(), [2]);
        assert!(a.list::<u8>("none").unwrap().is_empty());
        let mut empty = args(serde_json::json!({"values": []}));
        assert!(empty.list::<String>("values").unwrap_err().message.contains("\"values\" is an empty list"));
        assert!(a.list::<u8>("bad").unwrap_err().message.contains("not a list"));
        let mut a = args(serde_json::json!({"position": -1, "vel": 1}));
        let e = a.need::<u32>("position").unwrap_err();
        assert!(e.message.starts_with("move position \"-1\": ") && e.kind == "usage", "{}", e.message);
        assert!(a.need::<u32>("actuator").unwrap_err().message.contains("\"actuator\" is missing"));
        let mut b = args(serde_json::json!({"items": ["a", "b"], "item": "c"}));
        assert!(b.one_or_many("item", "items").unwrap_err().message.contains("not both"));
        let mut b = args(serde_json::json!({"items": "a"}));
        assert_eq!(b.one_or_many("item", "items").unwrap(), (vec!["a".to_string()], true));
        let mut b = args(serde_json::json!({"item": "a"}));
        assert_eq!(b.one_or_many("item", "items").unwrap(), (vec!["a".to_string()], false));
        let mut b = args(serde_json::json!({"items": []}));
        assert!(b.one_or_many("item", "items").unwrap_err().message.contains("empty"));
        let mut b = args(serde_json::json!({}));
        assert!(b.one_or_many("item", "items").unwrap_err().message.contains("\"item\" is missing"));
        let e = a.finish().unwrap_err();
        assert!(
            e.message.contains("unknown argument \"vel\"") && e.message.contains("position, actuator"),
            "{}",
            e.message
        );
    }
}
