"""The model: a SymPy Lagrangian with its constraints, forces and contacts, validated and
analysed (:class:`~galerkin_vi.model.system.LagrangianSystem`)."""
