//! Sensor layout: positions relative to the pivot and the sums every estimate reuses.

use nalgebra::{Matrix3, Matrix4, SymmetricEigen, Vector3, Vector4};

use crate::{math, TiltError};

/// Capacity of a [`Layout`]; positions are stored inline so that no estimate allocates.
pub const MAX_SENSORS: usize = 64;

/// Relative eigenvalue threshold below which `sum p_i p_i^T` or the least-squares normal
/// matrix is treated as singular.
const RANK_TOL: f64 = 1e-10;

/// An affine plane `{x : normal . x = offset}` (unit normal, `offset > 0`) holding every sensor.
///
/// With such a layout the linear least-squares problem is rank deficient and the Fisher
/// information is singular when omega is parallel to `normal` (spec section 6.3).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AffinePlane {
    /// Unit normal of the plane.
    pub normal: Vector3<f64>,
    /// Distance of the plane from the pivot (positive).
    pub offset: f64,
}

/// Accelerometer positions `p_i` (body frame, metres, relative to the pivot) with the
/// precomputed `P = sum p_i p_i^T`, `p = sum p_i`, the pseudo-inverse of the least-squares
/// normal matrix, and optional calibrated biases subtracted from every measurement.
#[derive(Debug, Clone)]
pub struct Layout {
    positions: [Vector3<f64>; MAX_SENSORS],
    biases: [Vector3<f64>; MAX_SENSORS],
    len: usize,
    p_outer: Matrix3<f64>,
    p_sum: Vector3<f64>,
    z_pinv: Matrix4<f64>,
    plane: Option<AffinePlane>,
}

impl Layout {
    /// Builds a layout; rejects fewer than 3 sensors, non-finite positions and positions that
    /// do not span R^3 (all on a plane through the pivot).
    ///
    /// ```
    /// use nalgebra::Vector3;
    /// let layout = tilt::Layout::new(&[
    ///     Vector3::new(1.0, 0.0, 0.0),
    ///     Vector3::new(0.0, 1.0, 0.0),
    ///     Vector3::new(0.0, 0.0, 1.0),
    ///     Vector3::new(0.2, 0.2, 0.2) / 3f64.sqrt(),
    /// ])?;
    /// assert_eq!(layout.len(), 4);
    /// assert!(layout.affine_plane().is_none());
    /// # Ok::<(), tilt::TiltError>(())
    /// ```
    pub fn new(positions: &[Vector3<f64>]) -> Result<Self, TiltError> {
        let len = positions.len();
        if len < 3 {
            return Err(TiltError::TooFewSensors { got: len });
        }
        if len > MAX_SENSORS {
            return Err(TiltError::TooManySensors {
                got: len,
                max: MAX_SENSORS,
            });
        }
        let mut stored = [Vector3::zeros(); MAX_SENSORS];
        let mut p_outer = Matrix3::zeros();
        let mut p_sum = Vector3::zeros();
        for (i, p) in positions.iter().enumerate() {
            if !p.iter().all(|v| v.is_finite()) {
                return Err(TiltError::NonFinitePosition { sensor: i });
            }
            stored[i] = *p;
            p_outer += p * p.transpose();
            p_sum += p;
        }
        let eig_p = SymmetricEigen::new(p_outer).eigenvalues;
        let max_p = eig_p.max();
        let rank = eig_p.iter().filter(|&&l| l > RANK_TOL * max_p).count();
        if max_p <= 0.0 || rank < 3 {
            return Err(TiltError::PositionsDoNotSpan { rank });
        }
        let (z_pinv, plane) = normal_matrix_pinv(&p_outer, &p_sum, len);
        Ok(Self {
            positions: stored,
            biases: [Vector3::zeros(); MAX_SENSORS],
            len,
            p_outer,
            p_sum,
            z_pinv,
            plane,
        })
    }

    /// Same layout with calibrated accelerometer biases, subtracted from every measurement
    /// before estimation (the paper calibrates its sensors beforehand; Table 3 shows the
    /// error an uncorrected bias causes).
    pub fn with_biases(mut self, biases: &[Vector3<f64>]) -> Result<Self, TiltError> {
        if biases.len() != self.len {
            return Err(TiltError::MeasurementCount {
                expected: self.len,
                got: biases.len(),
            });
        }
        for (i, b) in biases.iter().enumerate() {
            if !b.iter().all(|v| v.is_finite()) {
                return Err(TiltError::NonFiniteBias { sensor: i });
            }
            self.biases[i] = *b;
        }
        Ok(self)
    }

    /// Number of sensors L.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Always false: a layout holds at least three sensors.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The sensor positions.
    pub fn positions(&self) -> &[Vector3<f64>] {
        &self.positions[..self.len]
    }

    /// The calibrated biases (zero unless set by [`Layout::with_biases`]).
    pub fn biases(&self) -> &[Vector3<f64>] {
        &self.biases[..self.len]
    }

    /// `P = sum p_i p_i^T`.
    pub fn p_outer(&self) -> &Matrix3<f64> {
        &self.p_outer
    }

    /// `p = sum p_i` (the paper's p is the sum, not the mean).
    pub fn p_sum(&self) -> &Vector3<f64> {
        &self.p_sum
    }

    /// `Theta = tr(P) I - P = sum -[p_i]x^2`.
    pub fn theta(&self) -> Matrix3<f64> {
        Matrix3::identity() * self.p_outer.trace() - self.p_outer
    }

    /// Moore-Penrose pseudo-inverse of `Z = [[P, p], [p^T, L]]` (the inverse when the sensors
    /// are not all on one affine plane).
    pub fn z_pinv(&self) -> &Matrix4<f64> {
        &self.z_pinv
    }

    /// The affine plane (not through the pivot) holding all sensors, if any: then the linear
    /// least-squares problem is rank deficient and omega along its normal is unobservable.
    pub fn affine_plane(&self) -> Option<AffinePlane> {
        self.plane
    }

    /// Checks the count and finiteness of one sample and returns the bias-corrected sums
    /// `(m, mbar) = (sum m_i, sum m_i p_i^T)`.
    pub(crate) fn sample_sums(
        &self,
        measurements: &[Vector3<f64>],
    ) -> Result<(Vector3<f64>, Matrix3<f64>), TiltError> {
        self.check(measurements)?;
        let mut m_sum = Vector3::zeros();
        let mut m_bar = Matrix3::zeros();
        for ((m, b), p) in measurements.iter().zip(self.biases()).zip(self.positions()) {
            let corrected = m - b;
            m_sum += corrected;
            m_bar += corrected * p.transpose();
        }
        Ok((m_sum, m_bar))
    }

    /// Rejects a sample of the wrong length or with a non-finite entry.
    pub(crate) fn check(&self, measurements: &[Vector3<f64>]) -> Result<(), TiltError> {
        if measurements.len() != self.len {
            return Err(TiltError::MeasurementCount {
                expected: self.len,
                got: measurements.len(),
            });
        }
        match measurements
            .iter()
            .position(|m| !m.iter().all(|v| v.is_finite()))
        {
            Some(sensor) => Err(TiltError::NonFiniteMeasurement { sensor }),
            None => Ok(()),
        }
    }

    /// Least-squares cost `J = 1/2 sum |m_i - b_i - Omega p_i + g|^2` of a candidate.
    pub fn cost(
        &self,
        measurements: &[Vector3<f64>],
        omega_matrix: &Matrix3<f64>,
        g: &Vector3<f64>,
    ) -> Result<f64, TiltError> {
        self.check(measurements)?;
        Ok(measurements
            .iter()
            .zip(self.biases())
            .zip(self.positions())
            .map(|((m, b), p)| (m - b - omega_matrix * p + g).norm_squared())
            .sum::<f64>()
            * 0.5)
    }
}

/// Pseudo-inverse of `Z = sum z_i z_i^T`, `z_i = (p_i, 1)`, and the affine plane of the sensors
/// when `Z` is singular (then its null vector `(n, beta)` satisfies `n . p_i + beta = 0`).
/// The rank test runs on `Z` rescaled to unit sensor radius so that it does not depend on the
/// length unit; `P` has full rank here, so `Z` has at most one null direction.
fn normal_matrix_pinv(
    p_outer: &Matrix3<f64>,
    p_sum: &Vector3<f64>,
    len: usize,
) -> (Matrix4<f64>, Option<AffinePlane>) {
    let mut z = Matrix4::zeros();
    z.fixed_view_mut::<3, 3>(0, 0).copy_from(p_outer);
    z.fixed_view_mut::<3, 1>(0, 3).copy_from(p_sum);
    z.fixed_view_mut::<1, 3>(3, 0).copy_from(&p_sum.transpose());
    z[(3, 3)] = len as f64;
    let scale = math::sqrt(p_outer.trace() / len as f64);
    let d = Matrix4::from_diagonal(&Vector4::new(1.0 / scale, 1.0 / scale, 1.0 / scale, 1.0));
    let scaled = SymmetricEigen::new(d * z * d).eigenvalues;
    let singular = scaled.min() <= RANK_TOL * scaled.max();
    let eig = SymmetricEigen::new(z);
    let null = eig.eigenvalues.imin();
    let mut pinv = Matrix4::zeros();
    for (k, lambda) in eig.eigenvalues.iter().enumerate() {
        if !(singular && k == null) {
            let u = eig.eigenvectors.column(k);
            pinv += u * u.transpose() / *lambda;
        }
    }
    let plane = singular.then(|| {
        let v = eig.eigenvectors.column(null);
        let n = Vector3::new(v[0], v[1], v[2]);
        let n_norm = n.norm();
        let sign = if v[3] > 0.0 { -1.0 } else { 1.0 };
        AffinePlane {
            normal: n * (sign / n_norm),
            offset: (v[3] / n_norm).abs(),
        }
    });
    (pinv, plane)
}
