"""Contact: normal force laws (``laws``), their parameters from material data or a target
restitution (``parameters``), the one-degree-of-freedom impact that measures them (``single_impact``),
what a law allows and how finely a contact must be stepped (``resolution``), and contacts as the
physics defines them at a model's time resolution (``intervals``)."""
