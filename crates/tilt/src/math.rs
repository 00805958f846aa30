//! Scalar functions that work with and without `std` (through nalgebra's `ComplexField`,
//! which uses `libm` in `no_std` builds).

use nalgebra::ComplexField;

pub(crate) fn sqrt(x: f64) -> f64 {
    ComplexField::sqrt(x)
}

pub(crate) fn ln(x: f64) -> f64 {
    ComplexField::ln(x)
}

pub(crate) fn exp(x: f64) -> f64 {
    ComplexField::exp(x)
}

pub(crate) fn sin(x: f64) -> f64 {
    ComplexField::sin(x)
}

pub(crate) fn cos(x: f64) -> f64 {
    ComplexField::cos(x)
}
