//! Bit-exact serialisation of the floating-point numbers in algorithm *state*.
//!
//! A paused algorithm must resume bit-identically, but a JSON float parser need not be correctly
//! rounded (serde_json's default parser is not: about one value in ten written with 17 digits reads
//! back one unit in the last place off), and JSON has no infinity. So state fields holding floats
//! are written as strings of Rust's shortest round-trip decimal form (`Debug` of `f64`, e.g. `"0.1"`,
//! `"1e-7"`, `"inf"`) and read back with the correctly rounded `str::parse`. Summaries, which are
//! for people and never resumed, keep plain numbers.
//!
//! Used as `#[serde(with = "crate::inference::exact")]` on fields of type `f64`, `Vec<f64>`,
//! `Option<f64>`, `Vec<Vec<f64>>` and other nestings of `Vec` and `Option` around `f64`.

use serde::de::{self, Visitor};
use serde::{Deserialize, Deserializer, Serialize, Serializer};

/// A value whose floats are written as exact decimal strings.
pub(crate) trait Exact: Sized {
    fn ser<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error>;
    fn de<'de, D: Deserializer<'de>>(d: D) -> Result<Self, D::Error>;
}

/// Borrowing adaptor: `Serialize` through [`Exact`].
struct Ser<'a, T>(&'a T);

impl<T: Exact> Serialize for Ser<'_, T> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        self.0.ser(s)
    }
}

/// Owning adaptor: `Deserialize` through [`Exact`].
struct De<T>(T);

impl<'de, T: Exact> Deserialize<'de> for De<T> {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        T::de(d).map(De)
    }
}

struct F64Visitor;

impl Visitor<'_> for F64Visitor {
    type Value = f64;

    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str("a floating-point number written as a string, e.g. \"0.25\" or \"inf\"")
    }

    fn visit_str<E: de::Error>(self, v: &str) -> Result<f64, E> {
        v.parse::<f64>().map_err(|_| E::invalid_value(de::Unexpected::Str(v), &self))
    }
}

impl Exact for f64 {
    fn ser<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        // written straight into the output: no temporary string per float
        s.collect_str(&format_args!("{self:?}"))
    }

    fn de<'de, D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        d.deserialize_str(F64Visitor)
    }
}

impl<T: Exact> Exact for Vec<T> {
    fn ser<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_seq(self.iter().map(Ser))
    }

    fn de<'de, D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        Vec::<De<T>>::deserialize(d).map(|v| v.into_iter().map(|x| x.0).collect())
    }
}

impl<T: Exact> Exact for Option<T> {
    fn ser<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match self {
            Some(x) => s.serialize_some(&Ser(x)),
            None => s.serialize_none(),
        }
    }

    fn de<'de, D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        Option::<De<T>>::deserialize(d).map(|o| o.map(|x| x.0))
    }
}

pub(crate) fn serialize<T: Exact, S: Serializer>(value: &T, s: S) -> Result<S::Ok, S::Error> {
    value.ser(s)
}

pub(crate) fn deserialize<'de, T: Exact, D: Deserializer<'de>>(d: D) -> Result<T, D::Error> {
    T::de(d)
}

/// A [`crate::Space`] with exactly round-tripping bounds, rebuilt (and so re-validated) on reading.
pub(crate) mod space {
    use super::*;
    use crate::space::{FreeParameter, Scale, Space};

    #[derive(Serialize, Deserialize)]
    struct Param {
        name: String,
        #[serde(with = "super")]
        lower: f64,
        #[serde(with = "super")]
        upper: f64,
        scale: Scale,
    }

    pub(crate) fn serialize<S: Serializer>(space: &Space, s: S) -> Result<S::Ok, S::Error> {
        s.collect_seq(space.params().iter().map(|p| Param {
            name: p.name.clone(),
            lower: p.lower,
            upper: p.upper,
            scale: p.scale,
        }))
    }

    pub(crate) fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Space, D::Error> {
        let params = Vec::<Param>::deserialize(d)?;
        Space::new(
            params
                .into_iter()
                .map(|p| FreeParameter { name: p.name, lower: p.lower, upper: p.upper, scale: p.scale })
                .collect(),
        )
        .map_err(de::Error::custom)
    }
}

#[cfg(test)]
mod tests {
    #[derive(serde::Serialize, serde::Deserialize, PartialEq, Debug)]
    struct State {
        #[serde(with = "super")]
        x: Vec<Option<f64>>,
    }

    #[test]
    fn round_trips_every_float_bit_for_bit() {
        let specials = [0.1 + 0.2, -0.0, f64::INFINITY, f64::NEG_INFINITY, 5e-324, f64::MAX, 1.0 / 3.0, 1e-7];
        let state = State { x: specials.iter().map(|&v| Some(v)).chain([None, Some(f64::NAN)]).collect() };
        let json = serde_json::to_string(&state).unwrap();
        let back: State = serde_json::from_str(&json).unwrap();
        let bits = |s: &State| s.x.iter().map(|v| v.map(f64::to_bits)).collect::<Vec<_>>();
        assert_eq!(bits(&back), bits(&state), "{json}");
        assert!(serde_json::from_str::<State>(r#"{"x":["abc"]}"#).is_err());
    }
}
