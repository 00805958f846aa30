//! Parametrized infinite-horizon MPC with Laguerre basis functions and semi-infinite constraints.
