//! Simulator, MCAP logging, model workbench and the `stabilis` command-line runner.
