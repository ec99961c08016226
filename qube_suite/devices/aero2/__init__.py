"""The Quanser Aero 2: domains `aero2` and `aero2_hardware`.

Files, in the order a new device needs them: `parameters.py` (the table, by long name, with
sources), `conventions.py` (state, action, signs, counts to SI), `model.xml` and `scene.xml`
(the MJCF), `simulation.py` (the MuJoCo domain), `tasks.py` (`SUITE`), `hardware.py` (the board
domain), `controllers.py` (the classical baselines), then this declaration.
"""
