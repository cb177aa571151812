"""Building a palette: every primitive of the set sized and verified on the 3D model,
regulators, braking maneuvers, catches and shifts, in worker processes."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from gracenav.control import ControllerGains, design_gains
from gracenav.palette.palette import REGULATOR_NAME, Palette, palette_key
from gracenav.params import BallbotParams
from gracenav.policies import (
    CatchOptions,
    DomainShape,
    MotionPolicy,
    RegulatorOptions,
    SampledPrimitive,
    VerificationOptions,
)
from gracenav.policies.catches import (
    PUSHED,
    SETTLED,
    STILL,
    catch_policies,
    shift_cells,
    shift_policies,
)
from gracenav.primitives import PrimitiveSetOptions

__all__ = ["build_palette"]


def _size_one(
    args: tuple[SampledPrimitive, ControllerGains, VerificationOptions, DomainShape],
) -> tuple[MotionPolicy, ...]:
    """The policy of one primitive sized by bisection, then its verified larger variants
    and its fine copies; those that pass and start at rest are verified from the still
    band too (:func:`gracenav.policies.catches.verify_still_start`)."""
    from gracenav.policies import fine_variants, scaled_variants, size_policy
    from gracenav.policies.catches import verify_still_start

    prim, gains, options, shape = args
    base = size_policy(prim, gains, options, shape=shape)
    if base.report is None or not base.report.passed:
        return (base,)
    kept = (base, *scaled_variants(base, options), *fine_variants(base, options))
    return tuple(
        verify_still_start(p, options) if p.report is not None and p.report.passed else p
        for p in kept
    )


def _regulators(
    args: tuple[ControllerGains, VerificationOptions, DomainShape],
) -> tuple[MotionPolicy, ...]:
    """The capture regulators of ``options.regulator`` (see
    :func:`gracenav.policies.regulator_policies`), verified."""
    from gracenav.policies import regulator_policies
    from gracenav.primitives import TrimPrimitive

    gains, options, shape = args
    reg = options.regulator
    if reg is None:
        return ()
    zero = np.zeros(2)
    prim = SampledPrimitive.from_primitive(
        TrimPrimitive(REGULATOR_NAME, reg.duration, zero, zero, zero, gains.params)
    )
    goal = shape.radii(options.goal_position_extent)
    return regulator_policies(prim, gains, options, goal, shape.correlation)


def _braking_one(
    args: tuple[float, tuple[int, int], float, ControllerGains, VerificationOptions, DomainShape],
) -> tuple[MotionPolicy, ...]:
    """One braking maneuver (see :mod:`gracenav.policies.braking`), planned and verified at every
    size; empty if no stopping distance is feasible."""
    from gracenav.policies.braking import braking_policies, braking_primitive

    speed, direction, step, gains, options, shape = args
    assert options.braking is not None
    prim = braking_primitive(speed, direction, step, options.braking, gains)
    if prim is None:
        return ()
    return braking_policies(prim, gains, options, shape)


def _catch_classes(speed: float, options: CatchOptions) -> tuple[str, ...]:
    """The lean classes of the catches from ``speed`` (m/s) the options ask for."""
    return (
        *((PUSHED,) if speed in options.speeds else ()),
        *((SETTLED,) if speed in options.speeds or speed in options.settled_speeds else ()),
        *((STILL,) if speed in options.still_speeds else ()),
    )


def _catch_one(
    args: tuple[float, tuple[str, ...], ControllerGains, VerificationOptions, DomainShape],
) -> tuple[MotionPolicy, ...]:
    """The catches of some lean classes from one speed (see
    :func:`gracenav.policies.catches.catch_policies`)."""
    from gracenav.policies import push_lean_table

    speed, classes, gains, options, shape = args
    pushes = options.regulator or RegulatorOptions()  # the regulators' push table
    push_leans = push_lean_table(gains, pushes.push_impulses, pushes.push_times)
    return catch_policies(speed, gains, options, shape, push_leans, classes=classes)


def _shift_one(
    args: tuple[tuple[int, int], float, ControllerGains, VerificationOptions, DomainShape],
) -> tuple[MotionPolicy, ...]:
    """One shift (see :func:`gracenav.policies.catches.shift_policies`)."""
    cell, d, gains, options, shape = args
    return shift_policies(cell, d, gains, options, shape)


def _rotation_duplicate(prim: SampledPrimitive, earlier: Sequence[SampledPrimitive]) -> str | None:
    """Name of an earlier primitive of which ``prim`` is a 90°, 180° or 270° rotation."""
    for other in earlier:
        if other.kind is not prim.kind or other.num_ticks != prim.num_ticks:
            continue
        for k in (1, 2, 3):
            c, s = ((0.0, 1.0), (-1.0, 0.0), (0.0, -1.0))[k - 1]
            rot = np.array([[c, -s], [s, c]])
            pos = other.position.reshape(-1, 3, 2) @ rot.T
            if np.allclose(pos.reshape(-1, 6), prim.position, rtol=0.0, atol=1e-9):
                return f"{other.name} rotated by {90 * k}°"
    return None


def build_palette(
    primitives: Sequence[SampledPrimitive],
    *,
    d: float,
    params: BallbotParams | None = None,
    gains: ControllerGains | None = None,
    options: VerificationOptions | None = None,
    processes: int = 2,
    progress: bool = True,
    primitive_options: PrimitiveSetOptions | None = None,
) -> Palette:
    """Size and verify one policy per primitive, then its larger-domain variants; keep
    those that pass.

    Each primitive's policy is sized by bisection on S/G up to ``options.max_scale``;
    then the sizes of ``options.scale_ladder`` are verified in turn
    (:func:`gracenav.policies.scaled_variants`) and every one that passes is kept as a
    labelled variant sharing the primitive (instantiation places the largest that fits);
    last its fine copies (``options.fine_scales``, :func:`gracenav.policies.fine_variants`).

    Parameters
    ----------
    primitives : sequence of SampledPrimitive
        The primitive set Σ(d), sampled at the control rate.
    d : float
        Distance parameter (m).
    params : BallbotParams, optional
        Plant and nominal controller parameters.
    gains : ControllerGains, optional
        Control law (default: :func:`gracenav.control.design_gains` on ``params``).
    options : VerificationOptions, optional
    processes : int
        Worker processes (1 runs in this process).
    progress : bool
        Show a progress bar on a terminal.
    primitive_options : PrimitiveSetOptions, optional
        The options the primitives were planned with (recorded in the palette and its
        key; default the defaults).

    Returns
    -------
    Palette
    """
    from gracenav._util.progress import Progress
    from gracenav.policies import domain_shape

    params = params if params is not None else BallbotParams()
    gains = gains if gains is not None else design_gains(params)
    options = options if options is not None else VerificationOptions()
    prim_options = primitive_options if primitive_options is not None else PrimitiveSetOptions()
    shape = domain_shape(gains, horizon=options.shape_horizon)
    unique: list[SampledPrimitive] = []
    duplicates: list[tuple[str, str]] = []
    for prim in primitives:
        dup = _rotation_duplicate(prim, unique)
        if dup is None:
            unique.append(prim)
        else:
            duplicates.append((prim.name, dup))
    jobs = [(p, gains, options, shape) for p in unique]
    brk = options.braking
    brake_jobs = (
        []
        if brk is None
        else [
            (v, dirn, d / brk.lattice_divisions, gains, options, shape)
            for v in brk.speeds
            for dirn in brk.directions
        ]
    )
    cat = options.catch
    catch_jobs = (
        []
        if cat is None
        else [
            (v, _catch_classes(v, cat), gains, options, shape)
            for v in sorted({*cat.speeds, *cat.settled_speeds, *cat.still_speeds})
        ]
    )
    shift_jobs = [] if cat is None else [(c, d, gains, options, shape) for c in shift_cells(cat, d)]
    results: list[MotionPolicy] = []
    catches: list[MotionPolicy] = []
    shifts: list[MotionPolicy] = []
    total = (
        len(jobs)
        + len(brake_jobs)
        + len(catch_jobs)
        + len(shift_jobs)
        + (options.regulator is not None)
    )
    with Progress(total, "verifying policies", enabled=progress) as bar:
        if processes <= 1:
            for job in jobs:
                results.extend(_size_one(job))
                bar.update()
            if options.regulator is not None:
                results.extend(_regulators((gains, options, shape)))
                bar.update()
            for bjob in brake_jobs:
                results.extend(_braking_one(bjob))
                bar.update()
            for cjob in catch_jobs:
                catches.extend(_catch_one(cjob))
                bar.update()
            for sjob in shift_jobs:
                shifts.extend(_shift_one(sjob))
                bar.update()
        else:
            import multiprocessing as mp
            from concurrent.futures import ProcessPoolExecutor

            ctx = mp.get_context("fork") if "fork" in mp.get_all_start_methods() else None
            with ProcessPoolExecutor(max_workers=processes, mp_context=ctx) as pool:
                # The regulators (the longest job) first, so that they overlap the rest.
                regs = (
                    pool.submit(_regulators, (gains, options, shape))
                    if options.regulator is not None
                    else None
                )
                brakes = [pool.submit(_braking_one, bjob) for bjob in brake_jobs]
                catch_futs = [pool.submit(_catch_one, cjob) for cjob in catch_jobs]
                shift_futs = [pool.submit(_shift_one, sjob) for sjob in shift_jobs]
                for sized in pool.map(_size_one, jobs):
                    results.extend(sized)
                    bar.update()
                for fut in brakes:
                    results.extend(fut.result())
                    bar.update()
                for fut in catch_futs:
                    catches.extend(fut.result())
                    bar.update()
                for fut in shift_futs:
                    shifts.extend(fut.result())
                    bar.update()
                if regs is not None:
                    results.extend(regs.result())
                    bar.update()

    def verified(pols: list[MotionPolicy]) -> tuple[MotionPolicy, ...]:
        return tuple(p for p in pols if p.report is not None and p.report.passed)

    passed = verified(results)
    rejected = tuple(
        (p.name, p.report)
        for p in (*results, *catches, *shifts)
        if p.report is not None and not p.report.passed
    )
    return Palette(
        policies=passed,
        rejected=rejected,
        duplicates=tuple(duplicates),
        d=d,
        params=params,
        options=options,
        key=palette_key(params, gains, options, d, prim_options),
        primitive_options=prim_options,
        catches=verified(catches),
        shifts=verified(shifts),
    )
