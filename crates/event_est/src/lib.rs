//! Distributed event-based state estimation: agent runtime and LMI synthesis of gains and thresholds.
#![cfg_attr(not(feature = "std"), no_std)]
