"""Simulation models: the truth the flight code is flown against.

The inspector and its thrusters (vehicle, vehicles, log_description), the
relative orbit and rigid-body plant (orbit, plant), the physical effects
(effects), the sensors (sensors, camera, image_pose), the modal structures
(structure), the controller and the docking scenario (controller,
scenario_docking), flight logs (flight_log), any described vehicle flown
open loop (vehicle_sim) and docking runs with effects written as logs
(reality). Imports only bench.so3, bench.runner and bench.report of the
bench (tests/py/test_architecture.py)."""
