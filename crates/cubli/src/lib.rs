//! Reaction-wheel 3D inverted pendulum: model, backstepping balance, feedback linearization, jump-up learning.
#![cfg_attr(not(feature = "std"), no_std)]
