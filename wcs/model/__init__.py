"""The forward evaluation of one data set: the assembled model (`model`), the map from data to
coefficients (`coefficients`, `materials`), the criteria Φ (`criteria`), their adjoint gradients
(`sensitivity`), the solution fields and their validity (`fields`, `validity`), and the
`Evaluator` that meshes and assembles once and then evaluates data sets (`evaluation`).

It knows no study file: `Evaluator(study)` reads what it needs of a study's plain data (the
scene, the uncertain entries, the criteria, the solver options) and is built by whoever runs
the study (`wcs.app`)."""
