//! Serialisation of the floats of an algorithm's state that survives any format bit for bit
//! (shared by `optim` and `inference`).
//!
//! A resumed run must continue exactly as the uninterrupted one. Plain `f64` fields do not
//! guarantee that: JSON cannot hold `+∞` (the rank of a failed evaluation), and `serde_json` without
//! its `float_roundtrip` feature parses some 17-digit decimals to a neighbouring float. So state
//! floats are written as strings of their shortest round-trip decimal (`"0.30000000000000004"`,
//! `"inf"`), which Rust's correctly rounded parser reads back exactly. Options stay plain numbers.
//!
//! Used as `#[serde(with = "exact")]` on fields of type `f64`, `Vec<_>`, `Option<_>` and nalgebra's
//! dynamic matrices and vectors.

use nalgebra::{DMatrix, DVector};
use serde::de::{self, DeserializeOwned, Visitor};
use serde::{Deserialize, Deserializer, Serialize, Serializer};

/// An `f64` written as its shortest round-trip decimal string.
pub(crate) struct ExactF64(f64);

impl Serialize for ExactF64 {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        // written straight into the output: no temporary string per float
        s.collect_str(&format_args!("{:?}", self.0))
    }
}

struct ExactVisitor;

impl Visitor<'_> for ExactVisitor {
    type Value = ExactF64;

    fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("a float written as a decimal string, e.g. \"0.25\" or \"inf\"")
    }

    fn visit_str<E: de::Error>(self, v: &str) -> Result<ExactF64, E> {
        v.parse::<f64>().map(ExactF64).map_err(|_| E::invalid_value(de::Unexpected::Str(v), &self))
    }
}

impl<'de> Deserialize<'de> for ExactF64 {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        d.deserialize_str(ExactVisitor)
    }
}

/// A state type whose floats are written exactly.
pub(crate) trait Exact: Sized {
    /// The serialised form.
    type Repr: Serialize + DeserializeOwned;
    fn to_repr(&self) -> Self::Repr;
    fn from_repr(r: Self::Repr) -> Result<Self, String>;
}

impl Exact for f64 {
    type Repr = ExactF64;
    fn to_repr(&self) -> ExactF64 {
        ExactF64(*self)
    }
    fn from_repr(r: ExactF64) -> Result<Self, String> {
        Ok(r.0)
    }
}

impl<T: Exact> Exact for Vec<T> {
    type Repr = Vec<T::Repr>;
    fn to_repr(&self) -> Self::Repr {
        self.iter().map(Exact::to_repr).collect()
    }
    fn from_repr(r: Self::Repr) -> Result<Self, String> {
        r.into_iter().map(T::from_repr).collect()
    }
}

impl<T: Exact> Exact for Option<T> {
    type Repr = Option<T::Repr>;
    fn to_repr(&self) -> Self::Repr {
        self.as_ref().map(Exact::to_repr)
    }
    fn from_repr(r: Self::Repr) -> Result<Self, String> {
        r.map(T::from_repr).transpose()
    }
}

impl Exact for DVector<f64> {
    type Repr = Vec<ExactF64>;
    fn to_repr(&self) -> Self::Repr {
        self.iter().map(|&v| ExactF64(v)).collect()
    }
    fn from_repr(r: Self::Repr) -> Result<Self, String> {
        Ok(DVector::from_vec(r.into_iter().map(|v| v.0).collect()))
    }
}

/// A matrix as `(rows, columns, column-major entries)`.
impl Exact for DMatrix<f64> {
    type Repr = (usize, usize, Vec<ExactF64>);
    fn to_repr(&self) -> Self::Repr {
        (self.nrows(), self.ncols(), self.iter().map(|&v| ExactF64(v)).collect())
    }
    fn from_repr((rows, cols, data): Self::Repr) -> Result<Self, String> {
        if rows.checked_mul(cols) != Some(data.len()) {
            return Err(format!("a {rows}×{cols} matrix cannot have {} entries", data.len()));
        }
        Ok(DMatrix::from_vec(rows, cols, data.into_iter().map(|v| v.0).collect()))
    }
}

/// `serialize_with` half of `#[serde(with = "exact")]`.
pub(crate) fn serialize<T: Exact, S: Serializer>(v: &T, s: S) -> Result<S::Ok, S::Error> {
    v.to_repr().serialize(s)
}

/// `deserialize_with` half of `#[serde(with = "exact")]`.
pub(crate) fn deserialize<'de, T: Exact, D: Deserializer<'de>>(d: D) -> Result<T, D::Error> {
    let r = T::Repr::deserialize(d)?;
    T::from_repr(r).map_err(de::Error::custom)
}

/// A [`Space`](crate::space::Space) with its bounds written exactly: `#[serde(with = "exact::space")]`.
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
    use super::*;

    #[derive(Serialize, Deserialize, Debug, PartialEq)]
    struct S {
        #[serde(with = "super")]
        v: Vec<Option<f64>>,
        #[serde(with = "super")]
        m: DMatrix<f64>,
    }

    #[test]
    fn special_and_17_digit_values_round_trip_through_json() {
        let v = vec![Some(0.1 + 0.2), Some(f64::INFINITY), Some(-0.0), Some(5e-324), None, Some(1.0 / 3.0)];
        let s = S { v: v.clone(), m: DMatrix::from_row_slice(2, 3, &[1.0, 2.0, 3.0, 4.0, 5.0, 0.1 + 0.7]) };
        let json = serde_json::to_string(&s).unwrap();
        let back: S = serde_json::from_str(&json).unwrap();
        let bits = |v: &[Option<f64>]| v.iter().map(|x| x.map(f64::to_bits)).collect::<Vec<_>>();
        assert_eq!(bits(&back.v), bits(&v));
        assert_eq!(back.m, s.m);
        assert!(json.contains("\"inf\""));
        let nan: ExactF64 = serde_json::from_str("\"NaN\"").unwrap();
        assert!(nan.0.is_nan());
        assert!(serde_json::from_str::<S>(r#"{"v": [], "m": [2, 2, ["1.0"]]}"#).is_err());
    }
}
