"""The integrator registry: names, codes, orthonormalization options, orders (pure Python).

``rblog.engine.integrators`` re-exports everything here beside the compiled drifts; this module
imports nothing (not numpy, not the core), so that the CLI can offer the choices in ``--help``
without loading the engine.
"""

from __future__ import annotations

from dataclasses import dataclass

# orthonormalization codes
ORTHO_NONE = 0
ORTHO_POLAR = 1
ORTHO_GRAM_SCHMIDT = 2
ORTHO_NORMALIZE = 3  # quaternion normalization (seed-quat, splitting, rk4)
ORTHO_CODES = {"none": ORTHO_NONE, "polar": ORTHO_POLAR, "gram-schmidt": ORTHO_GRAM_SCHMIDT,
               "normalize": ORTHO_NORMALIZE}


@dataclass(frozen=True)
class Integrator:
    """One entry of the registry.

    Attributes:
        name: what a scene's ``[sim] integrator`` and ``--integrator`` say.
        code: the METHOD_* code the compiled kernels branch on.
        ortho_allowed: the ``orthonormalize`` options it accepts; ortho_default: the default.
        order: global order of accuracy in dt (torque-free rotation).
        summary: one line for ``--explain`` and the docs.
    """

    name: str
    code: int
    ortho_allowed: tuple[str, ...]
    ortho_default: str
    order: int
    summary: str


# integrator codes used by the kernels
METHOD_SEED = 0
METHOD_SEED_QUAT = 1
METHOD_SPLITTING = 2
METHOD_RK4 = 3
METHOD_EXACT = 4
METHOD_EXACT4 = 5
#: Yoshida (1990) triple-jump weights of the fourth-order composition of a symmetric step
YOSHIDA_W1 = 1.0 / (2.0 - 2.0 ** (1.0 / 3.0))
YOSHIDA_W0 = 1.0 - 2.0 * YOSHIDA_W1

#: The registry. To add an integrator: give it a code and an entry here, a ``drift_*`` for its
#: torque-free rotation over h with L fixed (dispatched by :func:`drift_rotation`, which the
#: contact step uses for every body), and its whole free step, translation and torque included,
#: in step_body (csrc/engine/free.cpp, the free-body kernel). In scenes with contacts the
#: contact step kicks P and L and translates by symplectic Euler for every integrator (see
#: rblog.engine.contact.step), so a free body's flight there is first order whatever the
#: integrator (issue: exact ballistic flight in every scene).
REGISTRY = {
    "seed": Integrator("seed", METHOD_SEED, ("polar", "gram-schmidt", "none"), "polar", 1,
                       "the notes: symplectic Euler on P and L, R += h [omega]x R, orthonormalized"),
    "seed-quat": Integrator("seed-quat", METHOD_SEED_QUAT, ("normalize", "none"), "normalize", 1,
                            "the notes on the quaternion: q += h/2 (0, omega) q, normalized"),
    "splitting": Integrator("splitting", METHOD_SPLITTING, ("normalize",), "normalize", 2,
                            "Strang splitting into exact axis rotations (symplectic)"),
    "rk4": Integrator("rk4", METHOD_RK4, ("normalize",), "normalize", 4,
                      "RK4 on Euler's equations, CF4 attitude aligned to L; exact constant-force translation"),
    "exact": Integrator("exact", METHOD_EXACT, ("normalize",), "normalize", 2,
                        "exact torque-free flow (elliptic functions); Strang kicks for torque"),
    "exact4": Integrator("exact4", METHOD_EXACT4, ("normalize",), "normalize", 4,
                         "exact torque-free flow in Yoshida's 4th-order composition with torque kicks"),
}
#: views of the registry, by name
METHOD_CODES = {k: v.code for k, v in REGISTRY.items()}
METHOD_NAMES = {v.code: k for k, v in REGISTRY.items()}
ORTHO_ALLOWED = {k: (v.ortho_allowed, v.ortho_default) for k, v in REGISTRY.items()}

