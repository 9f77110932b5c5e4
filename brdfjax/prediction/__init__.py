"""Predicting geometry that was not measured: `cross_validation` (held-out incidences),
`discrepancy` (a Gaussian process on the model's log residual), `intervals` (conformal
predictive intervals) and `selection` (ranking models by how well they predict)."""
