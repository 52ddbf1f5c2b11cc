//! Reading a report.json back whole, whatever it holds. JSON has no NaN: serde_json writes a
//! non-finite `f64` as `null` (a refused run's sigmas, correlations and RMS), and reading that
//! `null` into an `f64` fails. [`from_str`] parses the JSON and deserializes it through
//! [`Lenient`], which hands `null` to a number as NaN and passes everything else on unchanged, so
//! every `Deserialize` type reads what it wrote (the one place this is decided).

use serde::de::{self, DeserializeOwned, DeserializeSeed, Visitor};
use serde_json::{Map, Value};

/// `T` from JSON text, a `null` where a number belongs read as NaN.
pub fn from_str<T: DeserializeOwned>(text: &str) -> Result<T, serde_json::Error> {
    let v: Value = serde_json::from_str(text)?;
    T::deserialize(Lenient(v))
}

/// A JSON value whose `null`s read as NaN where a number is expected.
struct Lenient(Value);

impl<'de> de::Deserializer<'de> for Lenient {
    type Error = serde_json::Error;

    fn deserialize_any<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Self::Error> {
        match self.0 {
            Value::Array(a) => visitor.visit_seq(Seq(a.into_iter())),
            Value::Object(m) => visitor.visit_map(Entries {
                iter: m.into_iter(),
                value: None,
            }),
            other => de::Deserializer::deserialize_any(other, visitor),
        }
    }

    fn deserialize_f64<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Self::Error> {
        match self.0 {
            Value::Null => visitor.visit_f64(f64::NAN),
            other => de::Deserializer::deserialize_f64(other, visitor),
        }
    }

    fn deserialize_f32<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Self::Error> {
        match self.0 {
            Value::Null => visitor.visit_f32(f32::NAN),
            other => de::Deserializer::deserialize_f32(other, visitor),
        }
    }

    fn deserialize_option<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Self::Error> {
        match self.0 {
            Value::Null => visitor.visit_none(),
            other => visitor.visit_some(Lenient(other)),
        }
    }

    fn deserialize_newtype_struct<V: Visitor<'de>>(
        self,
        _name: &'static str,
        visitor: V,
    ) -> Result<V::Value, Self::Error> {
        visitor.visit_newtype_struct(self)
    }

    fn deserialize_enum<V: Visitor<'de>>(
        self,
        name: &'static str,
        variants: &'static [&'static str],
        visitor: V,
    ) -> Result<V::Value, Self::Error> {
        de::Deserializer::deserialize_enum(self.0, name, variants, visitor)
    }

    serde::forward_to_deserialize_any! {
        bool i8 i16 i32 i64 i128 u8 u16 u32 u64 u128 char str string bytes byte_buf unit
        unit_struct seq tuple tuple_struct map struct identifier ignored_any
    }
}

/// An array's elements, each [`Lenient`].
struct Seq(std::vec::IntoIter<Value>);

impl<'de> de::SeqAccess<'de> for Seq {
    type Error = serde_json::Error;

    fn next_element_seed<T: DeserializeSeed<'de>>(
        &mut self,
        seed: T,
    ) -> Result<Option<T::Value>, Self::Error> {
        self.0
            .next()
            .map(|v| seed.deserialize(Lenient(v)))
            .transpose()
    }

    fn size_hint(&self) -> Option<usize> {
        Some(self.0.len())
    }
}

/// An object's entries: the keys as strings, the values [`Lenient`].
struct Entries {
    iter: <Map<String, Value> as IntoIterator>::IntoIter,
    value: Option<Value>,
}

impl<'de> de::MapAccess<'de> for Entries {
    type Error = serde_json::Error;

    fn next_key_seed<K: DeserializeSeed<'de>>(
        &mut self,
        seed: K,
    ) -> Result<Option<K::Value>, Self::Error> {
        match self.iter.next() {
            Some((k, v)) => {
                self.value = Some(v);
                seed.deserialize(Key(k)).map(Some)
            }
            None => Ok(None),
        }
    }

    fn next_value_seed<V: DeserializeSeed<'de>>(
        &mut self,
        seed: V,
    ) -> Result<V::Value, Self::Error> {
        let v = self
            .value
            .take()
            .ok_or_else(|| de::Error::custom("a value without its key"))?;
        seed.deserialize(Lenient(v))
    }
}

/// An object's key: a string, or a number written as one (serde_json writes a map's integer
/// keys as strings and reads them back so; `BTreeMap<u16, _>`).
struct Key(String);

macro_rules! key_number {
    ($($de:ident $visit:ident $t:ty),*) => {$(
        fn $de<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Self::Error> {
            match self.0.parse::<$t>() {
                Ok(n) => visitor.$visit(n),
                Err(_) => Err(de::Error::invalid_value(de::Unexpected::Str(&self.0), &visitor)),
            }
        }
    )*};
}

impl<'de> de::Deserializer<'de> for Key {
    type Error = serde_json::Error;

    fn deserialize_any<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Self::Error> {
        visitor.visit_string(self.0)
    }

    key_number! {
        deserialize_i8 visit_i8 i8, deserialize_i16 visit_i16 i16, deserialize_i32 visit_i32 i32,
        deserialize_i64 visit_i64 i64, deserialize_u8 visit_u8 u8, deserialize_u16 visit_u16 u16,
        deserialize_u32 visit_u32 u32, deserialize_u64 visit_u64 u64, deserialize_f64 visit_f64 f64
    }

    serde::forward_to_deserialize_any! {
        bool i128 u128 f32 char str string bytes byte_buf option unit unit_struct newtype_struct
        seq tuple tuple_struct map struct enum identifier ignored_any
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde::{Deserialize, Serialize};
    use std::collections::BTreeMap;

    #[derive(Debug, Serialize, Deserialize)]
    struct Inner {
        a: f64,
        arr: [f64; 3],
        opt: Option<f64>,
        n: u64,
    }

    #[derive(Debug, Serialize, Deserialize)]
    struct Outer {
        name: String,
        inner: Vec<Inner>,
        grid: Vec<Vec<f64>>,
        map: BTreeMap<String, f64>,
        by_number: BTreeMap<u16, f64>,
        #[serde(default)]
        missing: f64,
        flag: bool,
    }

    /// What serde_json writes for NaN (`null`) reads back as NaN wherever a number is, an
    /// absent option stays `None`, and everything else is exactly what was written.
    #[test]
    fn a_written_nan_reads_back_as_nan() {
        let o = Outer {
            name: "S1".into(),
            inner: vec![Inner {
                a: f64::NAN,
                arr: [1.5, f64::INFINITY, -2.0],
                opt: None,
                n: 7,
            }],
            grid: vec![vec![1.0, f64::NAN], vec![f64::NAN, 0.25]],
            map: [("roll".to_string(), f64::NAN), ("x".to_string(), 1.25)].into(),
            by_number: [(1, f64::NAN), (300, 2.5)].into(),
            missing: 3.0,
            flag: true,
        };
        let text = serde_json::to_string(&o).unwrap();
        assert!(text.contains("null"), "{text}");
        // Plain serde_json cannot read its own output back.
        assert!(serde_json::from_str::<Outer>(&text).is_err());
        let r: Outer = from_str(&text).unwrap();
        assert_eq!(r.name, "S1");
        assert!(r.inner[0].a.is_nan());
        assert_eq!(r.inner[0].arr[0], 1.5);
        assert!(r.inner[0].arr[1].is_nan());
        assert_eq!(r.inner[0].arr[2], -2.0);
        assert_eq!(r.inner[0].opt, None);
        assert_eq!(r.inner[0].n, 7);
        assert!(r.grid[0][1].is_nan() && r.grid[1][0].is_nan());
        assert_eq!((r.grid[0][0], r.grid[1][1]), (1.0, 0.25));
        assert!(r.map["roll"].is_nan());
        assert_eq!(r.map["x"], 1.25);
        assert!(r.by_number[&1].is_nan());
        assert_eq!(r.by_number[&300], 2.5);
        assert_eq!(r.missing, 3.0);
        assert!(r.flag);
        // Wrong types are still errors.
        assert!(from_str::<Inner>(r#"{"a": "x", "arr": [1,2,3], "opt": null, "n": 1}"#).is_err());
        assert!(from_str::<Inner>(r#"{"a": 1, "arr": [1,2], "opt": null, "n": 1}"#).is_err());
        assert!(from_str::<Inner>(r#"{"a": 1, "arr": [1,2,3], "opt": null, "n": null}"#).is_err());
    }
}
