//! Accelerometer-only tilt, angular velocity and angular acceleration estimation; Fisher information, sensor placement.
#![cfg_attr(not(feature = "std"), no_std)]
