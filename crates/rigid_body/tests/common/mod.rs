//! Shared test set-up: seeded proptest configuration.

use proptest::test_runner::{Config, RngSeed};

/// 256 cases with a fixed seed, so that every run checks the same inputs.
pub fn config() -> Config {
    Config {
        cases: 256,
        rng_seed: RngSeed::Fixed(0x5eed_1717),
        ..Config::default()
    }
}
