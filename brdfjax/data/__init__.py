"""Measurements and the files they come in: `measurements` (the `Measurements` every stage
takes, and the incidence groups that cross-validation holds out), `formats` (every reader
and writer) and `synthetic` (the stand-ins for the paper's samples)."""
