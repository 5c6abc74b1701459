"""The method: Galerkin discretisations and their numeric tables (quadrature rules,
interpolation bases, stage-form and velocity-stage tables)."""
