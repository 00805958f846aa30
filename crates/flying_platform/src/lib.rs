//! Ducted-fan flying platform: models with switchable physical effects, Gramian design, cascaded control, multisine experiments.
