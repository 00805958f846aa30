//! Physical parameters of the vehicle (spec §2, §3, Table 3) in SI units.

use crate::error::{require_positive, Error, Result};
use crate::geometry::{circumradius, j2, t11_nominal, v1_nominal, N_INPUTS};
use nalgebra::{SMatrix, SVector, Vector3};

/// Standard gravity used throughout the paper, m/s².
pub const G0: f64 = 9.81;

/// Structured input matrix of the hover model (spec §3.2, §7.2).
///
/// The entries are the ones the frequency response can identify with `m`, `l1` and `I1`
/// fixed (spec §6.5): the horizontal allocation `T11`, the vertical effectiveness
/// `b_z = T12 / m`, the differential-thrust block `V1` and the yaw row `T22 / I3`.
#[derive(Debug, Clone, PartialEq)]
pub struct InputMatrix {
    /// `T11` (2x9, dimensionless): local forces into body x/y. Columns of vertical inputs are 0.
    pub t11: SMatrix<f64, 2, 9>,
    /// `T12 / m` on the vertical inputs F1z F2z F3z, 1/kg.
    pub b_z: [f64; 3],
    /// `V1` on the vertical inputs (2x3, dimensionless); scaled by the circumradius.
    pub v1: SMatrix<f64, 2, 3>,
    /// `T22 / I3` on the tangential inputs F1y F2y F3y, 1/(kg m).
    pub t22_y: [f64; 3],
    /// `T22 / I3` on the vertical inputs F1z F2z F3z (thrust-to-yaw coupling), 1/(kg m).
    pub t22_z: [f64; 3],
}

impl InputMatrix {
    /// First-principles input matrix for mass `m`, lever arm `l1` and yaw inertia `i3`.
    pub fn nominal(mass: f64, l1: f64, i3: f64) -> Self {
        let yaw = -circumradius(l1) / i3;
        Self {
            t11: t11_nominal(),
            b_z: [1.0 / mass; 3],
            v1: v1_nominal(),
            t22_y: [yaw; 3],
            t22_z: [0.0; 3],
        }
    }

    /// The identified input matrix of the paper's appendix (spec §7.2).
    pub fn identified() -> Self {
        Self {
            t11: SMatrix::<f64, 2, 9>::from_row_slice(&[
                0.6966, -0.0311, 0.0, -0.3643, -0.7165, 0.0, -0.3867, 0.7286, 0.0, //
                0.0330, 0.8656, 0.0, 0.6447, -0.3826, 0.0, -0.6196, -0.3775, 0.0,
            ]),
            b_z: [0.0967, 0.0896, 0.0670],
            v1: SMatrix::<f64, 2, 3>::from_row_slice(&[
                0.0156, -0.3433, 0.3873, //
                0.4450, -0.2501, -0.2068,
            ]),
            t22_y: [-0.7062, -0.6859, -0.7037],
            t22_z: [-0.1536, -0.1030, -0.1076],
        }
    }

    /// Names of the flat input-parameter vector, in order (`t11_x_F1x`, ..., `t22_F3z`).
    pub fn parameter_names() -> Vec<String> {
        let mut names = Vec::with_capacity(27);
        for row in ["x", "y"] {
            for unit in 1..=3 {
                for axis in ["x", "y"] {
                    names.push(format!("t11_{row}_F{unit}{axis}"));
                }
            }
        }
        for unit in 1..=3 {
            names.push(format!("bz_F{unit}z"));
        }
        for row in ["x", "y"] {
            for unit in 1..=3 {
                names.push(format!("v1_{row}_F{unit}z"));
            }
        }
        for axis in ["y", "z"] {
            for unit in 1..=3 {
                names.push(format!("t22_F{unit}{axis}"));
            }
        }
        names
    }

    /// The flat parameter vector in the order of [`InputMatrix::parameter_names`].
    pub fn to_vector(&self) -> Vec<f64> {
        let mut v = Vec::with_capacity(27);
        for row in 0..2 {
            for unit in 0..3 {
                v.push(self.t11[(row, 3 * unit)]);
                v.push(self.t11[(row, 3 * unit + 1)]);
            }
        }
        v.extend_from_slice(&self.b_z);
        for row in 0..2 {
            for unit in 0..3 {
                v.push(self.v1[(row, unit)]);
            }
        }
        v.extend_from_slice(&self.t22_y);
        v.extend_from_slice(&self.t22_z);
        v
    }

    /// Sets all entries from a flat vector in the order of [`InputMatrix::parameter_names`].
    pub fn set_vector(&mut self, values: &[f64]) -> Result<()> {
        if values.len() != 27 {
            return Err(Error::Length {
                what: "input-matrix parameter vector",
                got: values.len(),
                expected: 27,
            });
        }
        if let Some(i) = values.iter().position(|v| !v.is_finite()) {
            return Err(Error::Invalid {
                name: "input-matrix parameter vector",
                reason: format!("entry {i} ({}) is not finite", Self::parameter_names()[i]),
            });
        }
        let mut it = values.iter().copied();
        let mut next = || it.next().unwrap_or(0.0);
        for row in 0..2 {
            for unit in 0..3 {
                self.t11[(row, 3 * unit)] = next();
                self.t11[(row, 3 * unit + 1)] = next();
            }
        }
        for b in &mut self.b_z {
            *b = next();
        }
        for row in 0..2 {
            for unit in 0..3 {
                self.v1[(row, unit)] = next();
            }
        }
        for t in &mut self.t22_y {
            *t = next();
        }
        for t in &mut self.t22_z {
            *t = next();
        }
        Ok(())
    }
}

/// Vehicle parameters. `Default` is the paper's appendix (Table 3, identified input matrix).
///
/// | field | symbol | unit | default |
/// |---|---|---|---|
/// | `mass` | m | kg | 8.0 |
/// | `l1` | l1 (half the triangle side) | m | 0.1 |
/// | `l3` | l3, flap forces below the CoG (identified) | m | 0.079 |
/// | `l3_design` | l3 design target | m | 0.17 |
/// | `i1` | I1, roll/pitch inertia | kg m² | 0.07 |
/// | `i3` | I3, yaw inertia | kg m² | 0.11 |
/// | `rotor_inertia` | C, fan rotor inertia about its axis | kg m² | 7e-6 |
/// | `hover_torque` | M, net fan reaction torque at hover (assumption) | N m | 0.05 |
/// | `g0` | gravity | m/s² | 9.81 |
/// | `input` | structured input matrix | see [`InputMatrix`] | Table 3 |
#[derive(Debug, Clone, PartialEq)]
pub struct PlatformParams {
    /// Total mass m, kg.
    pub mass: f64,
    /// Half the side of the unit triangle l1, m.
    pub l1: f64,
    /// Vertical lever arm l3 of the flap forces below the CoG (identified value), m.
    pub l3: f64,
    /// Design target for l3 (spec §4), m.
    pub l3_design: f64,
    /// Roll/pitch inertia I1, kg m².
    pub i1: f64,
    /// Yaw inertia I3, kg m².
    pub i3: f64,
    /// Rotor inertia C of one fan about its axis, kg m².
    pub rotor_inertia: f64,
    /// Net reaction torque M of one fan at hover, N m (not reported; assumption).
    pub hover_torque: f64,
    /// Gravity g0, m/s².
    pub g0: f64,
    /// Structured input matrix.
    pub input: InputMatrix,
}

impl Default for PlatformParams {
    fn default() -> Self {
        Self {
            mass: 8.0,
            l1: 0.1,
            l3: 0.079,
            l3_design: 0.17,
            i1: 0.07,
            i3: 0.11,
            rotor_inertia: 7e-6,
            hover_torque: 0.05,
            g0: G0,
            input: InputMatrix::identified(),
        }
    }
}

impl PlatformParams {
    /// Table-3 scalars with the first-principles input matrix (the controller's design model).
    pub fn nominal() -> Self {
        let mut p = Self::default();
        p.input = InputMatrix::nominal(p.mass, p.l1, p.i3);
        p
    }

    /// Checks that mass, lengths and inertias are physical.
    pub fn validate(&self) -> Result<()> {
        require_positive("mass", self.mass)?;
        require_positive("l1", self.l1)?;
        require_positive("i1", self.i1)?;
        require_positive("i3", self.i3)?;
        require_positive("g0", self.g0)?;
        crate::error::require_finite("l3", self.l3)?;
        crate::error::require_finite("hover_torque", self.hover_torque)?;
        if self.rotor_inertia.is_nan() || self.rotor_inertia < 0.0 {
            return Err(Error::Invalid {
                name: "rotor_inertia",
                reason: format!("must be >= 0, got {}", self.rotor_inertia),
            });
        }
        Ok(())
    }

    /// Body-frame total force `T1 u` (N) of the thrust vector `u` (local frames, N).
    pub fn total_force(&self, u: &SVector<f64, N_INPUTS>) -> Vector3<f64> {
        let xy = self.input.t11 * u;
        let z: f64 = (0..3)
            .map(|i| self.mass * self.input.b_z[i] * u[3 * i + 2])
            .sum();
        Vector3::new(xy[0], xy[1], z)
    }

    /// Body-frame total torque about the CoG `T2 u` (N m) of the thrust vector `u`.
    pub fn total_torque(&self, u: &SVector<f64, N_INPUTS>) -> Vector3<f64> {
        let xy = j2() * (self.input.t11 * u) * self.l3;
        let uz = Vector3::new(u[2], u[5], u[8]);
        let diff = self.input.v1 * uz * circumradius(self.l1);
        let yaw: f64 = (0..3)
            .map(|i| {
                self.i3 * (self.input.t22_y[i] * u[3 * i + 1] + self.input.t22_z[i] * u[3 * i + 2])
            })
            .sum();
        Vector3::new(xy[0] + diff[0], xy[1] + diff[1], yaw)
    }

    /// Hover trim `u_bar` (spec §3.4): weight carried equally, fan torques cancelled by flap 2.
    pub fn hover_input(&self) -> SVector<f64, N_INPUTS> {
        let tangential = -self.hover_torque * 3f64.sqrt() / (2.0 * self.l1);
        let vertical = self.mass * self.g0 / 3.0;
        SVector::<f64, N_INPUTS>::from_column_slice(&[
            0.0, tangential, vertical, 0.0, tangential, vertical, 0.0, tangential, vertical,
        ])
    }
}
