//! The maximum-likelihood estimator: the projected fixed-point iteration (2.39)-(2.40) started
//! from the projected least-squares solution (2.51).

use nalgebra::{Matrix3, Vector3};

use rigid_body::{matrix_set, s2};

use crate::least_squares::{self, LeastSquaresEstimate};
use crate::tuning::{default_tuning, manual_tuning, Tuning};
use crate::{Layout, TiltError, G0};

/// Iteration settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Options {
    /// Step sizes and their certificate.
    pub tuning: Tuning,
    /// Relative change of both g and Omega below which the iteration stops (paper: 1e-8).
    pub tol: f64,
    /// Iteration budget; reaching it is reported as non-convergence.
    pub max_iterations: usize,
    /// Sine of the angle between the estimated omega and the normal of the sensors' affine
    /// plane below which the estimate is flagged as unidentifiable (only for layouts on one
    /// affine plane, e.g. three sensors). At the singular set the estimate wanders along the
    /// flat direction by about the square root of the noise, so the flag needs a margin: with
    /// three sensors 5 cm from the pivot, |omega| = 2 rad/s and 7.7e-4 m/s^2 noise the
    /// estimated sine reaches 0.13 when omega is exactly along the normal.
    pub plane_alignment_tol: f64,
}

impl Options {
    /// The paper's settings for a layout: `q = 1/L`, `r = r*`, tolerance 1e-8, at most 10 000
    /// iterations, plane-alignment flag below 0.2 (about 11.5 degrees).
    pub fn for_layout(layout: &Layout) -> Self {
        Self {
            tuning: default_tuning(layout),
            tol: 1e-8,
            max_iterations: 10_000,
            plane_alignment_tol: 0.2,
        }
    }

    /// Same options with the step sizes `q`, `r` given by the caller.
    pub fn with_step_sizes(self, layout: &Layout, q: f64, r: f64) -> Self {
        Self {
            tuning: manual_tuning(layout, q, r),
            ..self
        }
    }

    fn validate(&self) -> Result<(), TiltError> {
        let positive = |name: &'static str, value: f64| {
            if value > 0.0 && value.is_finite() {
                Ok(())
            } else {
                Err(TiltError::InvalidOption {
                    name,
                    value,
                    requirement: "must be positive and finite",
                })
            }
        };
        positive("q", self.tuning.q)?;
        positive("r", self.tuning.r)?;
        positive("tol", self.tol)?;
        if self.max_iterations == 0 {
            return Err(TiltError::InvalidOption {
                name: "max_iterations",
                value: 0.0,
                requirement: "must be at least 1",
            });
        }
        if self.plane_alignment_tol.is_nan() || self.plane_alignment_tol < 0.0 {
            return Err(TiltError::InvalidOption {
                name: "plane_alignment_tol",
                value: self.plane_alignment_tol,
                requirement: "must be non-negative",
            });
        }
        Ok(())
    }
}

/// One maximum-likelihood estimate with everything needed to judge it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Estimate {
    /// Gravity in the body frame (the tilt), on the sphere of radius g0.
    pub g: Vector3<f64>,
    /// `Omega = [omega]x^2 + [omega_dot]x`, an element of M.
    pub omega_matrix: Matrix3<f64>,
    /// Angular acceleration (rad/s^2).
    pub omega_dot: Vector3<f64>,
    /// `|omega|` (rad/s).
    pub omega_norm: f64,
    /// Angular velocity up to sign (unobservable): the component of largest magnitude is
    /// made positive.
    pub omega: Vector3<f64>,
    /// Number of updates performed.
    pub iterations: usize,
    /// Final cost `1/2 sum |m_i - Omega p_i + g|^2`.
    pub cost: f64,
    /// For layouts on one affine plane: sine of the angle between omega and the plane normal
    /// (tilt and omega become unidentifiable as it goes to 0; errors grow like its inverse).
    pub plane_alignment: Option<f64>,
    /// Conditions under which the estimate must not be trusted blindly.
    pub flags: Flags,
}

/// Diagnostic flags of an [`Estimate`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Flags {
    /// The stopping rule was met within the iteration budget.
    pub converged: bool,
    /// The step sizes satisfy the local-convergence certificate of Theorem 2.
    pub certified: bool,
    /// The sensors lie on one affine plane, so the least-squares start is the minimum-norm
    /// solution (not unique).
    pub min_norm_start: bool,
    /// omega is (nearly) parallel to the normal of the sensors' affine plane: the Fisher
    /// information is singular there, tilt and omega are not identifiable from this sample.
    pub omega_along_plane_normal: bool,
}

impl Estimate {
    /// Converged and identifiable.
    pub fn is_reliable(&self) -> bool {
        self.flags.converged && !self.flags.omega_along_plane_normal
    }
}

/// The maximum-likelihood tilt estimator for a fixed layout.
#[derive(Debug, Clone)]
pub struct Estimator {
    layout: Layout,
    options: Options,
}

impl Estimator {
    /// Estimator with the paper's default options for `layout`.
    pub fn new(layout: Layout) -> Self {
        let options = Options::for_layout(&layout);
        Self { layout, options }
    }

    /// Estimator with explicit options (validated).
    pub fn with_options(layout: Layout, options: Options) -> Result<Self, TiltError> {
        options.validate()?;
        Ok(Self { layout, options })
    }

    /// The layout.
    pub fn layout(&self) -> &Layout {
        &self.layout
    }

    /// The options.
    pub fn options(&self) -> &Options {
        &self.options
    }

    /// Estimates tilt, angular velocity and angular acceleration from one sample (one
    /// reading per sensor, body frame, m/s^2). Allocation-free.
    ///
    /// ```
    /// use nalgebra::Vector3;
    /// let positions = [
    ///     Vector3::new(1.0, 0.0, 0.0),
    ///     Vector3::new(0.0, 1.0, 0.0),
    ///     Vector3::new(0.0, 0.0, 1.0),
    ///     Vector3::new(0.2, 0.2, 0.2) / 3f64.sqrt(),
    /// ];
    /// let estimator = tilt::Estimator::new(tilt::Layout::new(&positions)?);
    /// let (omega, omega_dot) = (Vector3::new(0.3, -1.0, 0.5), Vector3::new(2.0, 0.0, -1.0));
    /// let g = Vector3::new(0.0, 6.0, -7.0).normalize() * tilt::G0;
    /// let mut m = [Vector3::zeros(); 4];
    /// tilt::ideal_measurements(&positions, &omega, &omega_dot, &g, &mut m);
    /// let estimate = estimator.estimate(&m)?;
    /// assert!(estimate.flags.converged && (estimate.g - g).norm() < 1e-6);
    /// assert!((estimate.omega_norm - omega.norm()).abs() < 1e-6);
    /// # Ok::<(), tilt::TiltError>(())
    /// ```
    pub fn estimate(&self, measurements: &[Vector3<f64>]) -> Result<Estimate, TiltError> {
        let (m_sum, m_bar) = self.layout.sample_sums(measurements)?;
        let ls = least_squares::from_sums(&self.layout, &m_sum, &m_bar);
        // A zero least-squares gravity (a null set) has no direction; start from "z up".
        let g0 = ls.g.unwrap_or(Vector3::new(0.0, 0.0, -G0));
        let start = matrix_set::project(&ls.omega_matrix)?;
        self.iterate(measurements, &m_sum, &m_bar, &ls, (start, g0))
    }

    /// Runs the iteration from a given start `(Omega_0, g_0)` (projected onto M x S^2 first);
    /// used to probe for other local minima.
    pub fn estimate_from(
        &self,
        measurements: &[Vector3<f64>],
        omega_matrix: &Matrix3<f64>,
        g: &Vector3<f64>,
    ) -> Result<Estimate, TiltError> {
        if !omega_matrix.iter().chain(g.iter()).all(|v| v.is_finite()) {
            return Err(TiltError::InvalidState("start point is not finite"));
        }
        let g0 = s2::project(g, G0)
            .map_err(|_| TiltError::InvalidState("start gravity has zero length"))?;
        let (m_sum, m_bar) = self.layout.sample_sums(measurements)?;
        let ls = least_squares::from_sums(&self.layout, &m_sum, &m_bar);
        self.iterate(
            measurements,
            &m_sum,
            &m_bar,
            &ls,
            (matrix_set::project(omega_matrix)?, g0),
        )
    }

    fn iterate(
        &self,
        measurements: &[Vector3<f64>],
        m_sum: &Vector3<f64>,
        m_bar: &Matrix3<f64>,
        ls: &LeastSquaresEstimate,
        start: (matrix_set::Projection, Vector3<f64>),
    ) -> Result<Estimate, TiltError> {
        let Options {
            tuning,
            tol,
            max_iterations,
            plane_alignment_tol,
        } = self.options;
        let (q, r) = (tuning.q, tuning.r);
        let big_p = self.layout.p_outer();
        let p = self.layout.p_sum();
        let l = self.layout.len() as f64;
        let (mut current, mut g) = start;
        let mut iterations = 0;
        let mut converged = false;
        while iterations < max_iterations {
            let omega = current.matrix;
            let next =
                matrix_set::project(&(omega + (m_bar - omega * big_p + g * p.transpose()) * r))?;
            let g_step = g - (m_sum - next.matrix * p + g * l) * q;
            // The gradient step lands on the origin only on a null set; keep g there.
            let g_next = s2::project(&g_step, G0).unwrap_or(g);
            iterations += 1;
            let d_omega = (next.matrix - omega).norm();
            let d_g = (g_next - g).norm();
            current = next;
            g = g_next;
            if d_g <= tol * G0 && (d_omega <= tol * current.matrix.norm() || d_omega == 0.0) {
                converged = true;
                break;
            }
        }
        let omega = current.matrix;
        let omega_norm = current.w.norm();
        let plane_alignment = self.layout.affine_plane().map(|plane| {
            if omega_norm > 0.0 {
                current.w.cross(&plane.normal).norm() / omega_norm
            } else {
                0.0
            }
        });
        let omega_along_plane_normal = plane_alignment.is_some_and(|s| s < plane_alignment_tol);
        let cost = self.layout.cost(measurements, &omega, &g)?;
        let finite = cost.is_finite()
            && omega_norm.is_finite()
            && g.iter()
                .chain(omega.iter())
                .chain(current.h.iter())
                .chain(current.w.iter())
                .all(|v| v.is_finite());
        if !finite {
            // Neither converged nor certified: no estimate at all.
            let largest = measurements.iter().map(|m| m.amax()).fold(0.0, f64::max);
            return Err(TiltError::Overflow { largest });
        }
        Ok(Estimate {
            g,
            omega_matrix: omega,
            omega_dot: current.h,
            omega_norm,
            omega: current.w,
            iterations,
            cost,
            plane_alignment,
            flags: Flags {
                converged,
                certified: tuning.certified(),
                min_norm_start: ls.rank_deficient,
                omega_along_plane_normal,
            },
        })
    }
}
