//! D-optimal accelerometer placement (spec section 6.4): maximise the determinant of the
//! expected Fisher information over sensors in the unit ball around the pivot.

use nalgebra::{Matrix3, Vector3};

use crate::{math, Layout, TiltError, MAX_SENSORS};

/// The D-criterion (2.64) `det(Theta) det(L g0^2 Theta - [p]x [g]x Pi Pi^T [g]x [p]x)` for
/// gravity `g` given in the body frame (`|g|` is used as g0). Orientation-free only when the
/// sensor centroid is at the pivot.
pub fn d_criterion(layout: &Layout, g: &Vector3<f64>) -> f64 {
    let theta = layout.theta();
    let l = layout.len() as f64;
    let gx = g.cross_matrix();
    let px = layout.p_sum().cross_matrix();
    // [g]x Pi Pi^T [g]x = [g]x (I - g g^T / |g|^2) [g]x = [g]x^2.
    let coupling = px * gx * gx * px;
    theta.determinant() * (theta * (l * g.norm_squared()) - coupling).determinant()
}

/// Upper bound `(L g0^2)^3 (2L/3)^6` of [`d_criterion`] over layouts in the unit ball,
/// attained exactly by the layouts with `p = 0` and `Theta = (2L/3) I` (Proposition 3).
pub fn d_criterion_bound(sensors: usize, g0: f64) -> f64 {
    let l = sensors as f64;
    let a = l * g0 * g0;
    let b = 2.0 * l / 3.0;
    a * a * a * b * b * b * b * b * b
}

/// Writes the vertices of a Platonic solid with `sensors` vertices (4, 6, 8, 12 or 20) on the
/// unit sphere into `out` and returns them as a slice: these layouts attain
/// [`d_criterion_bound`]. Other counts get [`TiltError::InvalidOption`].
///
/// ```
/// use nalgebra::Vector3;
/// let mut buffer = [Vector3::zeros(); tilt::MAX_SENSORS];
/// let tetrahedron = tilt::platonic_layout(4, &mut buffer)?;
/// let layout = tilt::Layout::new(tetrahedron)?;
/// let g = Vector3::new(0.0, 0.0, -tilt::G0);
/// let ratio = tilt::d_criterion(&layout, &g) / tilt::d_criterion_bound(4, tilt::G0);
/// assert!((ratio - 1.0).abs() < 1e-9);
/// # Ok::<(), tilt::TiltError>(())
/// ```
pub fn platonic_layout(
    sensors: usize,
    out: &mut [Vector3<f64>; MAX_SENSORS],
) -> Result<&[Vector3<f64>], TiltError> {
    let phi = 0.5 * (1.0 + math::sqrt(5.0));
    let mut n = 0;
    let mut push = |v: Vector3<f64>| {
        out[n] = v.normalize();
        n += 1;
    };
    let signs = [1.0, -1.0];
    match sensors {
        4 => {
            for v in [
                [1.0, 1.0, 1.0],
                [1.0, -1.0, -1.0],
                [-1.0, 1.0, -1.0],
                [-1.0, -1.0, 1.0],
            ] {
                push(Vector3::from(v));
            }
        }
        6 => {
            for k in 0..3 {
                for s in signs {
                    let mut v = Vector3::zeros();
                    v[k] = s;
                    push(v);
                }
            }
        }
        8 | 20 => {
            for x in signs {
                for y in signs {
                    for z in signs {
                        push(Vector3::new(x, y, z));
                    }
                }
            }
            if sensors == 20 {
                // Dodecahedron: the cube plus cyclic permutations of (0, +-1/phi, +-phi).
                for k in 0..3 {
                    for a in signs {
                        for b in signs {
                            let mut v = Vector3::zeros();
                            v[(k + 1) % 3] = a / phi;
                            v[(k + 2) % 3] = b * phi;
                            push(v);
                        }
                    }
                }
            }
        }
        12 => {
            // Icosahedron: cyclic permutations of (0, +-1, +-phi).
            for k in 0..3 {
                for a in signs {
                    for b in signs {
                        let mut v = Vector3::zeros();
                        v[(k + 1) % 3] = a;
                        v[(k + 2) % 3] = b * phi;
                        push(v);
                    }
                }
            }
        }
        _ => {
            return Err(TiltError::InvalidOption {
                name: "sensors",
                value: sensors as f64,
                requirement: "a Platonic solid has 4, 6, 8, 12 or 20 vertices",
            })
        }
    }
    Ok(&out[..sensors])
}

/// Distance of a layout from the optimality conditions (2.65): `|p|`, `|P - (L/3) I|_F` and
/// `max_i | |p_i| - 1 |` (all zero exactly for D-optimal layouts in the unit ball).
pub fn optimality_residuals(layout: &Layout) -> [f64; 3] {
    let l = layout.len() as f64;
    let isotropy = (layout.p_outer() - Matrix3::identity() * (l / 3.0)).norm();
    let radius = layout
        .positions()
        .iter()
        .map(|p| (p.norm() - 1.0).abs())
        .fold(0.0, f64::max);
    [layout.p_sum().norm(), isotropy, radius]
}
