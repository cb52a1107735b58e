"""The simulated workcell: the only place (with ita.scoring) that knows the as-built part.

`world.SimWorld` holds a pybullet DIRECT world (arm, as-built part, fixture, rack, tools,
stations) and a simulated clock; `ultrasonic` is the thickness gauge's physics; `faults`
the faults that tests and fault injection switch on; `person` what a person called to the
cell does to it (the time taken, obstacles removed, faults cleared).  Device-facing code (ita.robot,
ita.sensors) drives the simulator through these objects and never reads the truth itself.
"""
