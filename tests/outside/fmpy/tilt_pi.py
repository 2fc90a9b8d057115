"""A tilt controller written as a Python class and built into an FMI 2.0 co-simulation FMU by
pythonfmu (an exporter tiltsim did not write). tests/outside/fmpy/fmi.rs imports the FMU as tiltsim's
controller and checks every recorded command against these equations.

    e_k   = -theta_k                      (hold the body upright)
    I_k+1 = I_k + e_k * h
    u_k+1 = clamp(k_p * e_k + k_i * I_k+1, -u_max, u_max)
"""
from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real


class TiltPi(Fmi2Slave):
    author = "tiltsim tests"
    description = "Upright-holding PI tilt controller (pythonfmu)"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.theta_meas = 0.0
        self.u = 0.0
        self.integral = 0.0
        self.k_p = 10.0
        self.k_i = 5.0
        self.u_max = 0.0610865238198
        # A step at or after this time fails (do_step returns False): the tests' failing FMU.
        self.fail_at = -1.0
        self.register_variable(Real("theta_meas", causality=Fmi2Causality.input))
        self.register_variable(Real("u", causality=Fmi2Causality.output))
        self.register_variable(Real("integral", causality=Fmi2Causality.output))
        for name in ("k_p", "k_i", "u_max", "fail_at"):
            self.register_variable(
                Real(name, causality=Fmi2Causality.parameter, variability=Fmi2Variability.tunable)
            )

    def do_step(self, current_time, step_size):
        if 0.0 <= self.fail_at <= current_time:
            return False
        e = -self.theta_meas
        self.integral = self.integral + e * step_size
        u = self.k_p * e + self.k_i * self.integral
        self.u = min(max(u, -self.u_max), self.u_max)
        return True
