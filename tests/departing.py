"""A scene whose chain leaves the run link by link (``[chain] leave``, ``viz3d.departures``), for
the tests of departures in physics, the recorder and the viewer."""

G = 9.81
HAUL = """
[scene]
description = "test: a chain of 6 links hanging from a winch on a vertical guide, hauled up at 0.5 m/s"
[sim]
formulation = "ali3p"
integrator = "trapezoidal"
dt = 1e-3
t_end = 1.2
output_dt = 0.01
ali3p_alpha = 1e9
[[bodies]]
name = "winch"
shape = {type = "box", extents = [0.1, 0.1, 0.1]}
mass = 1.0
position = [0.0, 0.0, 0.0]
[chain]
n = 6
link_length = 0.2
radius = 0.02
mass = 2.0
anchor = [0.0, 0.0, 0.0]
direction = [0.0, 0.0, -1.0]
attach = "winch"
joint = "universal"
leave = true
leave_dt = 0.01
[[joints]]
name = "guide"
type = "prismatic"
body1 = "winch"
body2 = "ground"
point = [0.0, 0.0, 0.0]
axis = [0.0, 0.0, 1.0]
[[drives]]
name = "winch"
joint = "guide"
mode = "velocity"
kind = "ramp"
amplitude = 0.5
start = 0.0
duration = 0.2
"""
WINCH, LINK, N, L = 1.0, 2.0, 6, 0.2
