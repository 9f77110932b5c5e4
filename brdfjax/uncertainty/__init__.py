"""Uncertainty of the fitted parameters: `likelihood` (the posterior: likelihood, prior,
coordinates), `result` (what either method reports), `laplace` (the Gaussian at the mode,
in milliseconds), `mcmc` (emcee sampling) and `bands` (bands of curves and reflectance from
the draws)."""
