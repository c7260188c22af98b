"""orbits: Hill frame, Clohessy–Wiltshire relative motion, two-body truth, Sun and eclipse.

Modules (ARCHITECTURE §1): :mod:`orbits.hill` (H frame, relative states), :mod:`orbits.two_body`
(elements, Kepler propagation, nonlinear relative trajectory), :mod:`orbits.cw` (HCW state
transition, natural relative orbits), :mod:`orbits.environment` (Sun direction, Earth shadow),
:mod:`orbits.scenario_001` (the Table 1 geometry of paper 001).
"""
