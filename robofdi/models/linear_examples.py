"""The linear examples of the source papers, as documented nominal models (with the digests' repairs).

    helicopter()       Jiang & Chowdhury, IEEE TCST 2005, eqs. (42)–(43): helicopter in the vertical plane, T = 0.01 s
    aircraft_lateral() Guo, Jiang, Zhang & Wang, J. Syst. Eng. Electron. 2008, Sec. 4 (A reconstructed, labels repaired)
    aircraft_three_surfaces()  the same aircraft reduced: no pitch-rate output (a 5×6 C), one surface per axis
    chip_refiner()     Wang, book ch. 2 (Caccavale & Villani eds., 2003), Sec. 10.2: TMP chip-refiner motor load
    f16_vertical()     the seed-004 example class: a documented F-16-class vertical-plane model (see its docstring)

Every matrix is copied from the printed paper (Jiang & Chowdhury 2005; Guo et al. 2008; Wang, book ch. 2), repaired
where the printed text is damaged; each function says which entries are repaired and why.
"""
from __future__ import annotations

import numpy as np

from robofdi.models.linear import LinearModel

__all__ = ["helicopter", "HELICOPTER_NOISE", "aircraft_lateral", "aircraft_three_surfaces", "AIRCRAFT_DISTURBANCE",
           "chip_refiner", "CHIP_REFINER", "f16_vertical"]

#: Paper's noise covariances for the helicopter: process S (per sample, on x) and sensor Q (on y) — note the
#: paper's naming: S is the process covariance, Q the sensor one (Jiang & Chowdhury eq. (1)–(4), Sec. V).
HELICOPTER_NOISE = {"process": np.diag([0.1**2, 0.1**2, 0.01**2, 0.01**2]), "sensor": 0.2**2 * np.eye(3)}


def helicopter() -> LinearModel:
    """Helicopter in the vertical plane, discrete at T = 0.01 s — Jiang & Chowdhury (2005) eqs. (42)–(43).

    States (u, w, ω_y, θ): longitudinal and vertical velocity, pitch rate, pitch angle; inputs: collective and
    longitudinal cyclic; outputs (u, −w, ω_y) — the printed C has −1 on w, kept. As printed the plant is open-loop
    unstable (eig ≈ 1.3755). Units are not given by the paper (dimensionless "1").
    """
    A = [[0.9996, 0.0003, 0.0002, -0.0037],
         [0.0005, 0.9900, -0.0002, -0.0406],
         [0.0010, 0.0037, 1.0453, 10.5644],
         [0.0000, 0.0000, 0.0101, 1.0524]]
    B = [[0.0044, 0.0018],
         [0.0353, -0.0755],
         [-0.0559, 0.0454],
         [-0.0003, 0.0002]]
    C = [[1, 0, 0, 0],
         [0, -1, 0, 0],
         [0, 0, 1, 0]]
    return LinearModel(A, B, C, dt=0.01, state_names=["u_long", "w_vert", "pitch_rate", "pitch"],
                       input_names=["collective", "cyclic"], output_names=["y_u", "y_minus_w", "y_pitch_rate"])


#: The aircraft's disturbance direction E (6×1, ≈ the w column of A: a vertical gust) — Guo et al. (2008) Sec. 4.
AIRCRAFT_DISTURBANCE = np.array([[0.0486], [-0.9566], [0.0046], [0.0], [0.0], [0.0]])


def aircraft_lateral() -> LinearModel:
    """Continuous aircraft model of Guo, Jiang, Zhang & Wang (2008) Sec. 4 (their ref. [13]).

    A is the digest's reconstruction (the extraction split thin-space digit groups into cells: one spurious 0 per
    row removed, a reconstruction); B, C, E are as printed. Labels repaired from the matrix
    structure: states (u, w, q, v, p, r) [ft/s, ft/s, rad/s, ft/s, rad/s, rad/s], inputs (δ_EL, δ_ER, δ_AL, δ_AR,
    δ_R) [deg], outputs (q, p_s, r_s, α, β, w-rate) in deg / deg/s as C's 57.3 factors imply, the last one the raw w.
    E (``AIRCRAFT_DISTURBANCE``) is the model's unknown input.
    """
    A = [[-0.0156, 0.0480, -5.9420, 0.0021, 0, 0],
         [-0.0910, -0.9588, 138.3606, 0.0163, 0, 0],
         [0.0002, 0.0046, -1.0220, -0.0005, 0, -0.0029],
         [0, 0, 0, -0.2804, 6.2667, -150.1436],
         [0, 0, 0.0003, -0.1821, -3.4193, 0.6401],
         [0, 0, 0.0025, 0.0454, -0.0304, -0.4536]]
    B = [[0.0339, 0.0339, 0.0251, 0.0251, 0],
         [-0.1722, -0.1722, -0.1798, -0.1798, 0],
         [-0.0873, -0.0873, -0.0075, -0.0075, 0],
         [-0.3149, 0.3148, 0.0233, -0.0233, 0.1205],
         [-0.1892, 0.1890, -0.3465, 0.3465, 0.1236],
         [-0.1678, 0.1678, -0.0147, 0.0147, -0.0588]]
    C = [[0, 0, 57.2958, 0, 0, 0],
         [0, 0, 0, 0, 57.2569, 2.3696],
         [0, 0, 0, 0, -2.3696, 57.2468],
         [-0.0155, 0.3756, 0, 0, 0, 0],
         [0, 0, 0, 0.3760, 0, 0],
         [0, 1, 0, 0, 0, 0]]
    return LinearModel(A, B, C, E=AIRCRAFT_DISTURBANCE,
                       state_names=["u", "w", "q", "v", "p", "r"],
                       input_names=["elevator_left", "elevator_right", "aileron_left", "aileron_right", "rudder"],
                       output_names=["q_deg", "p_stab", "r_stab", "alpha", "beta", "w_meas"],
                       units={"state": ["ft/s", "ft/s", "rad/s", "ft/s", "rad/s", "rad/s"], "u": ["deg"] * 5,
                              "y": ["deg/s", "deg/s", "deg/s", "deg", "deg", "ft/s"]})


def aircraft_three_surfaces() -> LinearModel:
    """:func:`aircraft_lateral` reduced (robofdi's example, not the paper's): the pitch-rate output q_deg removed
    (C is 5×6, so C⁺C ≠ I) and one surface per axis kept — left elevator, left aileron, rudder. For these the SPR
    output condition of the adaptive law can be met (:func:`robofdi.observers.spr.spr_lyapunov_weight`); with all
    five surfaces it cannot (rank(C T B) = 4 < 5 on every 5-output variant)."""
    full = aircraft_lateral()
    keep_y, keep_u = [1, 2, 3, 4, 5], [0, 2, 4]
    return LinearModel(full.A, full.B[:, keep_u], full.C[keep_y], E=full.E, state_names=full.state_names,
                       input_names=[full.input_names[i] for i in keep_u],
                       output_names=[full.output_names[i] for i in keep_y],
                       units={"state": list(full.units["state"]), "u": ["deg"] * 3,
                              "y": [full.units["y"][i] for i in keep_y]})


#: Controller and observer data of the TMP example (Wang, ch. 2, Sec. 10.2): healthy gain f_H, state feedback K
#: (closed-loop poles 0.1, 0.2 with f_H included), observer L (poles ≈ 0.5, 0.2), set point r, window N, λ.
CHIP_REFINER = {"f_H": 10.0, "K": np.array([[0.175, 0.245]]), "L": np.array([[0.533], [0.467]]), "setpoint": 30.0,
                "window": 10, "threshold": 8.0}


def chip_refiner() -> LinearModel:
    """TMP chip-refiner motor-load model — Wang, book ch. 2, Sec. 10.2 (copied exactly), discrete, one sample.

    x(k+1) = A x + B f u + E ω,  y = C x + D f u + F μ, with the actuator (transfer-screw) gain f outside the model
    matrices: B and D here are the *unit-gain* input columns, the healthy gain f_H = 10 multiplies them
    (``CHIP_REFINER["f_H"]``). u: normalised chip feed, y: normalised motor load (both dimensionless). E is the
    process-noise direction, kept as the model's unknown input.
    """
    return LinearModel([[0.8, 0.5], [0.0, 0.9]], [[0.1], [0.5]], [[1.0, 1.0]], D=[[1.0]], E=[[0.5], [0.6]], dt=1.0,
                       state_names=["x1", "x2"], input_names=["chip_feed"], output_names=["motor_load"])


def f16_vertical() -> LinearModel:
    """A 5-state / 3-input / 3-output vertical-plane aircraft model (the class of the seed-004 example).

    The seed's own F-16 model (its ref. [16]) is lost in the extraction of the paper. This is the
    AIRC vertical-plane aircraft model of Maciejowski, *Multivariable Feedback Design* (Addison-Wesley 1989), the
    book's running example (continuous time):
    states (altitude [m], forward speed [m/s], pitch [rad], pitch rate [rad/s], vertical speed [m/s]),
    inputs (spoiler [deg], forward thrust [m/s²], elevator [deg]), outputs (altitude, forward speed, pitch). It
    matches the printed gain's 5×3 shape; it is NOT claimed to be the seed's model (C.2: no reproduction target).
    """
    A = [[0, 0, 1.1320, 0, -1.0],
         [0, -0.0538, -0.1712, 0, 0.0705],
         [0, 0, 0, 1.0, 0],
         [0, 0.0485, 0, -0.8556, -1.0130],
         [0, -0.2909, 0, 1.0532, -0.6859]]
    B = [[0, 0, 0],
         [-0.12, 1.0, 0],
         [0, 0, 0],
         [4.4190, 0, -1.6650],
         [1.5750, 0, -0.0732]]
    C = [[1, 0, 0, 0, 0], [0, 1, 0, 0, 0], [0, 0, 1, 0, 0]]
    return LinearModel(A, B, C, state_names=["altitude", "speed", "pitch", "pitch_rate", "vertical_speed"],
                       input_names=["spoiler", "thrust", "elevator"], output_names=["y_altitude", "y_speed", "y_pitch"],
                       units={"state": ["m", "m/s", "rad", "rad/s", "m/s"], "u": ["deg", "m/s^2", "deg"],
                              "y": ["m", "m/s", "rad"]})
