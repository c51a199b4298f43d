//! Sensitivity analysis, local refinement, variance and posterior estimation, model comparison.
