//! D-optimal accelerometer placement (spec section 6.4): maximise the determinant of the
//! expected Fisher information over sensors in the unit ball around the pivot.

use nalgebra::{Matrix3, Vector3};

use crate::{math, Layout, TiltError, G0, MAX_SENSORS};

/// The D-criterion (2.64) `det(Theta) det(L g0^2 Theta - [p]x [g]x Pi Pi^T [g]x [p]x)` for
/// gravity `g` given in the body frame (`|g|` is used as g0). Orientation-free only when the
/// sensor centroid is at the pivot.
pub fn d_criterion(layout: &Layout, g: &Vector3<f64>) -> f64 {
    criterion_of(layout.positions(), g)
}

/// [`d_criterion`] of raw positions.
fn criterion_of(positions: &[Vector3<f64>], g: &Vector3<f64>) -> f64 {
    let (p_outer, p_sum) = positions
        .iter()
        .fold((Matrix3::zeros(), Vector3::zeros()), |(o, s), p| {
            (o + p * p.transpose(), s + p)
        });
    let theta = Matrix3::identity() * p_outer.trace() - p_outer;
    let l = positions.len() as f64;
    let gx = g.cross_matrix();
    let px = p_sum.cross_matrix();
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

/// A D-optimal layout of `sensors` accelerometers on the unit sphere (scale it to the space
/// available): the Platonic solid when one has that many vertices, otherwise the result of a
/// projected gradient ascent of `log d_criterion` (gravity along -z) over points on the unit
/// sphere, started from a Fibonacci lattice. Returns the positions (in `out`) and their
/// criterion as a fraction of [`d_criterion_bound`] (1 means provably optimal). Every count
/// from 4 to 20 except 5 reaches 1; for five sensors the bound is not attainable (the Gram
/// matrix would need a unit vector orthogonal to (1,...,1) with all entries +-1/sqrt(5)) and
/// the ascent stops at 0.9846.
///
/// ```
/// use nalgebra::Vector3;
/// let mut buffer = [Vector3::zeros(); tilt::MAX_SENSORS];
/// let (positions, ratio) = tilt::optimal_placement(7, &mut buffer)?;
/// assert_eq!(positions.len(), 7);
/// assert!(ratio > 0.999);
/// # Ok::<(), tilt::TiltError>(())
/// ```
pub fn optimal_placement(
    sensors: usize,
    out: &mut [Vector3<f64>; MAX_SENSORS],
) -> Result<(&[Vector3<f64>], f64), TiltError> {
    if sensors < 4 {
        // Three vectors cannot have both zero sum and full span; L = 3 has no interior optimum
        // of the form (2.65).
        return Err(TiltError::InvalidOption {
            name: "sensors",
            value: sensors as f64,
            requirement: "D-optimal placement needs at least 4 sensors",
        });
    }
    if sensors > MAX_SENSORS {
        return Err(TiltError::TooManySensors {
            got: sensors,
            max: MAX_SENSORS,
        });
    }
    let g = Vector3::new(0.0, 0.0, -G0);
    let bound = d_criterion_bound(sensors, G0);
    if platonic_layout(sensors, out).is_ok() {
        return Ok((&out[..sensors], criterion_of(&out[..sensors], &g) / bound));
    }
    fibonacci_sphere(&mut out[..sensors]);
    ascend(&mut out[..sensors], &g);
    Ok((&out[..sensors], criterion_of(&out[..sensors], &g) / bound))
}

/// Near-uniform points on the unit sphere (golden-angle spiral).
fn fibonacci_sphere(points: &mut [Vector3<f64>]) {
    let n = points.len() as f64;
    let golden = core::f64::consts::PI * (3.0 - math::sqrt(5.0));
    for (i, point) in points.iter_mut().enumerate() {
        let z = 1.0 - (2.0 * i as f64 + 1.0) / n;
        let radius = math::sqrt((1.0 - z * z).max(0.0));
        let angle = golden * i as f64;
        *point = Vector3::new(radius * math::cos(angle), radius * math::sin(angle), z);
    }
}

/// Projected gradient ascent of `log d_criterion` on the product of unit spheres, with a
/// central-difference gradient and a backtracking step.
fn ascend(points: &mut [Vector3<f64>], g: &Vector3<f64>) {
    let objective = |pts: &[Vector3<f64>]| {
        let d = criterion_of(pts, g);
        if d > 0.0 {
            math::ln(d)
        } else {
            f64::NEG_INFINITY
        }
    };
    let n = points.len();
    let mut gradient = [Vector3::zeros(); MAX_SENSORS];
    let mut trial = [Vector3::zeros(); MAX_SENSORS];
    let mut value = objective(points);
    let mut step = 0.1;
    for _ in 0..2000 {
        const H: f64 = 1e-6;
        for i in 0..n {
            for k in 0..3 {
                let original = points[i][k];
                points[i][k] = original + H;
                let up = objective(points);
                points[i][k] = original - H;
                let down = objective(points);
                points[i][k] = original;
                gradient[i][k] = (up - down) / (2.0 * H);
            }
            // Tangent part only: the radius is fixed at one.
            let radial = points[i] * points[i].dot(&gradient[i]);
            gradient[i] -= radial;
        }
        let norm = gradient[..n].iter().map(|v| v.norm_squared()).sum::<f64>();
        if math::sqrt(norm) < 1e-10 {
            break;
        }
        loop {
            for i in 0..n {
                trial[i] = (points[i] + gradient[i] * step).normalize();
            }
            let candidate = objective(&trial[..n]);
            if candidate > value {
                points.copy_from_slice(&trial[..n]);
                value = candidate;
                step *= 1.5;
                break;
            }
            step *= 0.5;
            if step < 1e-14 {
                return;
            }
        }
    }
}
