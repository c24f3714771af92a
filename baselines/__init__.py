"""Reference integrators for the variational equations, built from the same
model definition as varint's own methods (heyoka Taylor, SUNDIALS CVODE,
SciPy DOP853)."""
