"""Contact: normal force laws (``laws``), their parameters from material data or a target
restitution (``parameters``) and the one-degree-of-freedom impact that measures them (``single_impact``)."""
