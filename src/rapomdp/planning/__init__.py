"""POMDP planning: flat and active-recognition (MOMDP) models, the SARSOP-style solvers,
policies as ``.npz`` artefacts, and ``.pomdp`` / ``.pomdpx`` I/O. See docs/planning.md."""
