//! Sphere projection and tangent projector.
#![allow(clippy::unwrap_used)]

use common::config;
use nalgebra::{Matrix3, Vector3};
use proptest::prelude::*;
use rigid_body::{s2, Error};

mod common;

fn vector(lim: f64) -> impl Strategy<Value = Vector3<f64>> {
    (-lim..lim, -lim..lim, -lim..lim)
        .prop_filter("nonzero", |(x, y, z)| x * x + y * y + z * z > 1e-6)
        .prop_map(|(x, y, z)| Vector3::new(x, y, z))
}

proptest! {
    #![proptest_config(config())]

    #[test]
    fn projection_is_on_the_sphere_idempotent_and_nearest(
        x in vector(30.0), others in prop::collection::vec(vector(1.0), 32), radius in 0.1..20.0,
    ) {
        let p = s2::project(&x, radius).unwrap();
        prop_assert!((p.norm() - radius).abs() < 1e-14 * radius);
        prop_assert!((p.normalize() - x.normalize()).norm() < 1e-15 * 4.0);
        prop_assert!((s2::project(&p, radius).unwrap() - p).norm() < 1e-14 * radius);
        let d = (x - p).norm();
        prop_assert!((d - (x.norm() - radius).abs()).abs() < 1e-12 * (1.0 + x.norm()));
        for o in &others {
            let q = o.normalize() * radius;
            prop_assert!((x - q).norm() >= d - 1e-12);
        }
    }

    #[test]
    fn tangent_projector_is_an_orthogonal_projector(x in vector(30.0), v in vector(5.0)) {
        let p = s2::tangent_projector(&x).unwrap();
        prop_assert!((p * p - p).norm() < 1e-15 * 10.0);
        prop_assert!((p - p.transpose()).norm() == 0.0);
        prop_assert!((p * x).norm() < 1e-15 * 10.0 * x.norm());
        // It fixes tangent vectors and has rank 2.
        let t = x.cross(&v);
        prop_assert!((p * t - t).norm() < 1e-14 * t.norm().max(1.0));
        prop_assert!((p.trace() - 2.0).abs() < 1e-15 * 4.0);
    }
}

#[test]
fn degenerate_input_is_reported() {
    let err = s2::project(&Vector3::zeros(), s2::G0).unwrap_err();
    assert_eq!(err, Error::ZeroVector { name: "x" });
    assert_eq!(
        err.to_string(),
        "x is the zero vector; its direction is undefined"
    );
    let err = s2::project(&Vector3::new(f64::NAN, 0.0, 1.0), s2::G0).unwrap_err();
    assert_eq!(err, Error::NonFinite { name: "x" });
    let err = s2::project(&Vector3::x(), -1.0).unwrap_err();
    assert!(err.to_string().starts_with("radius = -1 is invalid"));
    assert!(s2::tangent_projector(&Vector3::zeros()).is_err());
    // Tiny but nonzero vectors still have a direction.
    let p = s2::project(&Vector3::new(0.0, 0.0, -1e-300), s2::G0).unwrap();
    assert!(
        (s2::project(&Vector3::new(1e300, 1e300, 0.0), 1.0)
            .unwrap()
            .x
            - 0.5f64.sqrt())
        .abs()
            < 1e-15
    );
    assert_eq!(p, Vector3::new(0.0, 0.0, -s2::G0));
    assert_eq!(
        s2::tangent_projector(&Vector3::z()).unwrap(),
        Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, 0.0))
    );
}
