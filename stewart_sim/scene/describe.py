"""`scene-info`: the model a scene builds and its tables as every command reads them
(stewart_sim.scene.load.Scene: the scene and its [controller], [cueing], [case], [solver] and
[sensors] tables, parsed once)."""
from __future__ import annotations

import numpy as np

from controller.config import ControllerConfig, scene_axis
from stewart_fmu.integrators import IntegratorOptions
from stewart_fmu.kinematics import inverse_kinematics
from stewart_fmu.model import Model, PerLeg, is_per_leg

from stewart_sim.scene.case_config import Case
from stewart_sim.scene.cueing_config import OPTIMAL, CueingConfig, OptimalOptions
from stewart_sim.scene.load import Scene


def describe(scene: Scene) -> str:
    """The scene as text: name, effects, masses, m_d, home leg lengths, cond(J) at home, and
    its tables."""
    model = scene.model
    kin = inverse_kinematics(model, model.home)
    lines = [
        f"scene: {model.name}" + (f" ({model.source})" if model.source else ""),
        f"effects: {', '.join(model.effects) or 'none'} (platform and gravity always)",
        f"gravity: {format_vector(model.gravity)} m/s^2",
        f"platform: mass {model.platform_mass:g} kg, principal inertia "
        f"{format_vector(model.platform_inertia)} kg m^2",
        _describe_legs(model), _describe_drive(model), _describe_friction(model),
        f"stroke: [{_opt(model.leg_min)}, {_opt(model.leg_max)}] m",
        f"home pose: {format_vector(model.home)} (m, rad)",
        f"home leg lengths: {format_vector(kin.lengths)} m",
        f"cond(J) at home: {kin.cond:.6g} (rotational columns scaled by "
        f"{model.characteristic_length:.6g} m)",
        _describe_transmission(model), _describe_controller(model, scene.controller),
        _describe_case(scene.case), _describe_cueing(model, scene.cueing),
    ]
    if OPTIMAL in (model.extra.get("cueing") or {}):
        lines.append(_describe_optimal(scene.optimal))
    lines.append(_describe_solver(scene.solver, scene.has_solver))
    s = scene.sensors
    lines.append("sensors: ideal (the emulated device reports its plant's numbers)" if s.ideal
                 else f"sensors: encoder {s.encoder_resolution:g} m, force noise "
                      f"{s.force_noise:g} N, current noise {s.current_noise:g} A, latency "
                      f"{s.latency:g} s, seed {s.seed} (what the emulated device reports)")
    return "\n".join(lines)


def _describe_solver(o: IntegratorOptions, given: bool) -> str:
    """The in-process plant's integrator (`run`, `simulate`): the [solver] table or the default."""
    where = "[solver]" if given else "no [solver]: stability.default_options"
    return (f"solver: {o.method}, rtol {o.rtol:g}, atol {o.atol:g}, max_step {o.max_step:.6g} s "
            f"({where}; run and simulate in-process)")


def _describe_transmission(model: Model) -> str:
    """The compliant transmission and what it brings in, or that the drive is rigid."""
    tr = model.transmission
    if tr is None:
        return "transmission: none (rigid: each motor moves its leg directly; 12 states)"
    return (f"transmission: stiffness {tr.stiffness:g} N/m, damping {tr.damping:g} N s/m "
            f"between each motor and its leg (the motor side moves on its own: "
            f"{model.state_size} states)")


def _describe_controller(model: Model, cfg: ControllerConfig | None) -> str:
    """The [controller] table and the axis model `run` designs for."""
    if cfg is None:
        return "controller: none (run, compare and closed-loop sweeps need a [controller] table)"
    m = cfg.motor
    axis = scene_axis(model, cfg)
    load = "given" if cfg.load_mass is not None else "largest diagonal of Kane's [m] at home"
    return (f"controller: rate {cfg.rate:g} Hz, bandwidth {cfg.bandwidth:g} Hz, phase margin "
            f"{cfg.phase_margin:g} deg, feedforward {cfg.feedforward}; motor R "
            f"{m.resistance:g} ohm, L {m.inductance:g} H, Kt {m.torque_constant:g} N m/A, Ke "
            f"{m.back_emf:g} V s/rad, limits {m.current_limit:g} A and {m.voltage_limit:g} V; "
            f"each axis: constant load {axis.load_mass:.6g} kg ({load}), reflected drive "
            f"inertia {axis.reflected_mass:.6g} kg"
            + (" (the largest leg's)" if is_per_leg(model.drive.rotor_inertia) else ""))


def _describe_case(case: "Case | None") -> str:
    """The [case] table of a stiff or extreme scene (as stewart_sim.scene.case_config.case_of
    reads it, defaults filled in): what it runs and the outcome expected."""
    if case is None:
        return "case: none"
    extra = [f"step {case.step:g} s"]
    if case.motion == "hold":
        extra += [f"force_scale {case.force_scale:g}",
                  f"start_rates {format_vector(case.start_rates)}"]
    extra += [f"{name} {format_vector(v)}" for name, v in (("acceleration", case.acceleration),
                                                           ("target", case.target))
              if v is not None]
    return (f"case: {case.kind}, motion {case.motion} for {case.duration:g} s, expected "
            f"outcome {case.expect} ({', '.join(extra)}): {case.description}")


def _describe_cueing(model: Model, c: CueingConfig) -> str:
    """The [cueing] table as the washout reads it."""
    if "cueing" not in model.extra:
        return ("cueing: none (motion cueing uses the defaults of "
                "stewart_sim/scene/cueing_config.py)")
    return (f"cueing: classical washout; translational gain "
            f"{format_vector(c.translational_gain)}, limit "
            f"{format_vector(c.translational_limit)} m/s^2, high-pass order "
            f"{c.translational_order} at {format_vector(c.translational_frequency)} rad/s, damping "
            f"{format_vector(c.translational_damping)}"
            + (f", first-order break {format_vector(c.translational_first_order)} "
               "rad/s" if c.translational_order == 3 else "")
            + f"; tilt low-pass {c.tilt_frequency:g} rad/s, damping {c.tilt_damping:g}, rate "
            f"limit {c.tilt_rate_limit:.6g} rad/s ({np.rad2deg(c.tilt_rate_limit):.3g} deg/s), "
            f"limit {c.tilt_limit:g} rad; rotational gain {format_vector(c.rotational_gain)}, "
            f"limit {format_vector(c.rotational_limit)} rad/s, high-pass order "
            f"{c.rotational_order} at {format_vector(c.rotational_frequency)} rad/s"
            + (f", damping {format_vector(c.rotational_damping)}" if c.rotational_order == 2
               else "")
            + (f"; position limit {format_vector(c.position_limit)} m"
               if c.position_limit is not None else "")
            + f"; perceived at the head {format_vector(c.head)} m (platform frame)")


def _describe_optimal(o: OptimalOptions) -> str:
    """The [cueing.optimal] sub-table as the model-predictive cueing reads it."""
    tilt = ("the [cueing] tilt_rate_limit" if o.tilt_rate_limit is None
            else f"{o.tilt_rate_limit:.6g} rad/s")
    return (f"cueing.optimal: model-predictive cueing at {o.rate:g} Hz over {o.horizon:g} s "
            f"({round(o.horizon * o.rate)} steps), preview {'on' if o.preview else 'off'}; "
            f"margins: stroke {o.stroke_margin:g} m, force {o.force_margin:g}, voltage "
            f"{o.voltage_margin:g}; tilt rate limit {tilt}; weights: perception "
            f"{format_vector(o.perception_weight)}, position {format_vector(o.position_weight)}, "
            f"velocity {format_vector(o.velocity_weight)}, yaw {o.yaw_weight:g}, rate "
            f"{format_vector(o.rate_weight)}, acceleration "
            f"{format_vector(o.acceleration_weight)}, angular acceleration "
            f"{format_vector(o.angular_acceleration_weight)}, slack "
            f"{format_vector(o.slack_weight)}, terminal {o.terminal_weight:g}; OSQP tolerance "
            f"{o.tolerance:g}, at most {o.max_iter} iterations")


def _describe_legs(model: Model) -> str:
    """Leg part masses, or that the legs are massless."""
    lg = model.legs
    if lg is None:
        return "legs: none (massless)"
    moving = model.platform_mass + 6 * (lg.lower_mass + lg.upper_mass)
    return (f"legs: lower part {lg.lower_mass:g} kg (CoM {lg.lower_com:g} m from the base joint, "
            f"inertia {format_vector(lg.lower_inertia)} kg m^2), upper part {lg.upper_mass:g} kg (CoM "
            f"{lg.upper_com:g} m from the platform joint, inertia {format_vector(lg.upper_inertia)} "
            "kg m^2); "
            f"platform + 12 leg parts {moving:g} kg")


def _describe_drive(model: Model) -> str:
    """Drive parameters and m_d, or that there is none."""
    dr = model.drive
    if dr is None:
        return "drive: none (m_d = 0, not modelled)"
    md = format_vector(dr.reflected_masses) if is_per_leg(dr.rotor_inertia) else f"{dr.reflected_mass:.6g}"
    return (f"drive: gear ratio {dr.gear_ratio:g}, rotor inertia {per_leg_text(dr.rotor_inertia)} kg m^2, "
            f"pinion radius {dr.pinion_radius:g} m; m_d = zeta^2 I / r^2 = {md} kg")


def _describe_friction(model: Model) -> str:
    """Friction coefficients, or that there is none."""
    fr = model.friction
    if fr is None:
        return "friction: none"
    return f"friction: viscous {per_leg_text(fr.viscous)} N s/m, Coulomb {per_leg_text(fr.coulomb)} N"


def per_leg_text(value: PerLeg) -> str:
    """A per-leg value: one number (all legs), or the six of legs 1..6."""
    return f"{format_vector(value)} (legs 1..6)" if is_per_leg(value) else f"{value:g}"


def format_vector(a) -> str:
    """A vector as [a, b, c] with 6 significant digits."""
    return "[" + ", ".join(f"{v:.6g}" for v in np.ravel(a)) + "]"


def _opt(x: float | None) -> str:
    """A number, or 'none'."""
    return "none" if x is None else f"{x:g}"
