"""Physics backends behind one small interface: MJX, or MuJoCo C through a host callback.

The environment sees only ``Physics``: a state is an ``mjx.Data`` whose ``qpos``, ``qvel`` and
``qacc_warmstart`` are the physical state; ``step`` holds PD targets for ``substeps`` physics
steps and reports which bodies touched the ground; ``kinematics`` (always MJX, in JAX) makes the
link frames current for the observations. Both backends therefore produce observations with the
very same JAX code from the same ``qpos``/``qvel``.

* ``mjx``: ``mjx.step`` in a ``lax.scan``, implementation ``jax`` (every device) or ``warp``
  (NVIDIA GPUs; ``mujoco-mjx[warp]``).
* ``mujoco``: MuJoCo's own C engine, stepping the whole batch with ``mujoco.rollout``'s thread
  pool, called from inside the compiled loop through ``jax.pure_callback``. On a 2-core CPU this
  is about 8x faster than MJX (DESIGN.md, measured facts). Determinism: the solver's warm start
  is passed in explicitly (never left over from a thread's scratch data) and carried in
  ``data.qacc_warmstart``, estimated as the last substep's velocity change over ``dt``; so the
  same inputs give the same outputs whichever thread steps which environment, and a resumed run
  is bit-identical. MuJoCo's automatic reset on a diverging state is disabled, so a bad state
  comes back non-finite and the env resets it like MJX's.
* ``auto``: ``mujoco`` on a CPU, ``mjx`` on an accelerator.

Under ``shard_map`` each device's callback steps its own shard, at the same time as the other
devices': a call borrows one of as many thread pools (each with its own scratch data) as there are
local devices; by default a pool has the host's cores divided by the local devices (a 2-core CPU
run as two devices: one thread each).

MuJoCo C reports trouble (a NaN control, a diverging state) through ``mju_warning``, whose default
handler appends to ``MUJOCO_LOG.TXT`` in the working directory, once per affected rollout, with no
bound. ``WARNINGS`` replaces that handler as soon as a C backend is built: it counts the warnings per
message, and the training driver writes the counts into the run folder.
"""

from __future__ import annotations

import collections
import contextlib
import functools
import os
import queue
import threading

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from mujoco import mjx

BACKENDS = ("auto", "mjx", "mujoco")


class WarningCounter:
    """MuJoCo's warnings, counted per message (the simulation time stripped), instead of written
    to ``MUJOCO_LOG.TXT`` in the working directory. The handler is process-wide and is called
    from the rollout pool's threads, hence the lock."""

    def __init__(self):
        self._counts: collections.Counter[str] = collections.Counter()
        self._lock = threading.Lock()
        self.installed = False

    def install(self) -> None:
        """Routes MuJoCo's warnings here (idempotent)."""
        if not self.installed:
            mujoco.set_mju_user_warning(self._on_warning)
            self.installed = True

    def _on_warning(self, message: str) -> None:
        with self._lock:
            self._counts[message.split(" Time =")[0].strip()] += 1

    def take(self) -> dict[str, int]:
        """The warnings counted since the last ``take`` (message -> count), and a fresh count."""
        with self._lock:
            out, self._counts = dict(self._counts), collections.Counter()
        return out


WARNINGS = WarningCounter()
"""The process's MuJoCo warnings (``WarningCounter``); installed by the MuJoCo C backend."""


def resolve_backend(name: str) -> str:
    """``auto`` -> ``mujoco`` on a CPU, ``mjx`` on an accelerator; other names are checked."""
    if name not in BACKENDS:
        raise ValueError(f"physics backend {name!r} is not one of {BACKENDS}")
    if name != "auto":
        return name
    return "mujoco" if jax.default_backend() == "cpu" else "mjx"


def body_ground_contacts_mjx(m: mujoco.MjModel, data: mjx.Data, floor: str = "floor") -> jax.Array:
    """[nbody-1] bool: which bodies (world excluded) have a penetrating contact with the floor."""
    contact = data._impl.contact
    geom_body = jnp.asarray(m.geom_bodyid, jnp.int32)
    fid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, floor)
    body = geom_body[jnp.where(contact.geom[..., 0] == fid, contact.geom[..., 1], contact.geom[..., 0])]
    hit = (contact.dist < 0.0) & jnp.any(contact.geom == fid, axis=-1)
    touched = jnp.zeros((m.nbody,), bool).at[body].max(hit)
    return touched[1:]


def contact_normal_forces_mjx(data: mjx.Data) -> jax.Array:
    """[ncon] normal force of every contact slot of ``data`` (0 where inactive), as
    ``mj_contactForce``'s first component: the constraint row's force for a frictionless contact,
    the sum of the pyramid's edge forces for a pyramidal friction cone. The slots' rows are
    static, so this is one gather and a masked sum."""
    c, f = data._impl.contact, data._impl.efc_force
    adr, dim = np.asarray(c.efc_address), np.asarray(c.dim)
    if adr.shape[0] == 0:
        return jnp.zeros((0,), f.dtype)
    n = np.where(dim == 1, 1, 2 * (dim - 1))
    k = np.arange(max(int(n.max()), 1))
    rows = adr[:, None] + k[None]
    valid = (adr[:, None] >= 0) & (k[None] < n[:, None])
    return jnp.sum(jnp.where(valid, f[np.where(valid, rows, 0)], 0.0), -1)


def channel_forces_mjx(data: mjx.Data, channels) -> jax.Array:
    """[n_channels] summed normal force of each channel's geom pairs in ``data``."""
    if not channels:
        return jnp.zeros((0,), jnp.float32)
    force = contact_normal_forces_mjx(data)
    g = data._impl.contact.geom
    out = []
    for ch in channels:
        pairs = jnp.asarray(ch.pairs, jnp.int32)  # [P, 2]
        match = ((g[:, None, 0] == pairs[None, :, 0]) & (g[:, None, 1] == pairs[None, :, 1])) | (
            (g[:, None, 0] == pairs[None, :, 1]) & (g[:, None, 1] == pairs[None, :, 0])
        )
        out.append(jnp.sum(jnp.where(jnp.any(match, -1), force, 0.0)))
    return jnp.stack(out).astype(jnp.float32)


def _clamped_servo(model: mjx.Model, data: mjx.Data) -> tuple[mjx.Model, mjx.Data]:
    """The model and data of one MJX substep with every saturated PD actuator treated as MuJoCo C
    treats it.

    The servo is ``clip(kp*(ctrl - q) - kd*qdot, ±limit)``. With ``implicitfast`` MuJoCo C leaves an
    actuator whose force is clamped out of the implicit damping (its force no longer depends on
    qdot); MJX differentiates the unclamped bias and keeps it, so one saturated substep parted the
    engines by tens of rad/s. Here a saturated actuator gets ``kd = 0`` and the control whose
    undamped force is exactly its limit: the same force, and no implicit damping, as in C. An
    unsaturated actuator is unchanged. Every actuator is a position servo on one joint (``kp`` in
    ``gainprm[0]``, ``-kp, -kd`` in ``biasprm[1:3]``; ``physics/character.py``)."""
    trn = np.asarray(model.actuator_trnid)[:, 0]
    q = data.qpos[np.asarray(model.jnt_qposadr)[trn]]
    qd = data.qvel[np.asarray(model.jnt_dofadr)[trn]]
    kp, kd = model.actuator_gainprm[:, 0], -model.actuator_biasprm[:, 2]
    lo, hi = model.actuator_forcerange[:, 0], model.actuator_forcerange[:, 1]
    force = kp * (data.ctrl - q) - kd * qd
    limited = jnp.asarray(np.asarray(model.actuator_forcelimited, bool))
    sat = limited & ((force < lo) | (force > hi))
    edge = jnp.where(force > hi, hi, lo)
    ctrl = jnp.where(sat, q + edge / jnp.where(kp == 0, 1.0, kp), data.ctrl)
    bias = model.actuator_biasprm.at[:, 2].set(jnp.where(sat, 0.0, -kd))
    return model.replace(actuator_biasprm=bias), data.replace(ctrl=ctrl)


def mjx_substep(model: mjx.Model, data: mjx.Data) -> mjx.Data:
    """One MJX physics step holding ``data.ctrl``, with saturated servos as in MuJoCo C
    (``_clamped_servo``); the returned data keeps the PD targets as its ``ctrl``."""
    m, d = _clamped_servo(model, data)
    return mjx.step(m, d).replace(ctrl=data.ctrl)


class MJXPhysics:
    """MJX stepping (``impl`` 'jax' or 'warp')."""

    name = "mjx"

    def __init__(self, mj: mujoco.MjModel, model: mjx.Model, substeps: int, channels=()):
        self.mj = mj
        self.model = model
        self.substeps = substeps
        self.channels = tuple(channels)

    def step_forces(self, data: mjx.Data, target: jax.Array) -> tuple[mjx.Data, jax.Array, jax.Array]:
        """As ``step``, plus [n_channels] the maximum over the substeps of each force channel."""
        data = data.replace(ctrl=target)

        def sub(carry, _):
            d, fmax = carry
            d = mjx_substep(self.model, d)
            return (d, jnp.maximum(fmax, channel_forces_mjx(d, self.channels))), None

        f0 = jnp.zeros((len(self.channels),), jnp.float32)
        (data, forces), _ = jax.lax.scan(sub, (data, f0), None, length=self.substeps)
        return data, body_ground_contacts_mjx(self.mj, data), forces

    def step(self, data: mjx.Data, target: jax.Array) -> tuple[mjx.Data, jax.Array]:
        """Holds ``target`` for ``substeps`` MJX steps; returns (data, body ground contacts).

        The contacts are those of the last step's collision pass (one substep old)."""
        data = mjx_pd_step(self.model, data, target, self.substeps)
        return data, body_ground_contacts_mjx(self.mj, data)


def mjx_pd_step(model: mjx.Model, data: mjx.Data, target: jax.Array, substeps: int) -> mjx.Data:
    """Holds ``target`` joint positions with the model's PD actuators for ``substeps`` MJX steps."""
    data = data.replace(ctrl=target)
    data, _ = jax.lax.scan(lambda d, _: (mjx_substep(model, d), None), data, None, length=substeps)
    return data


def _with_ground_sensors(mj_xml: str, floor: str = "floor", channels=()) -> mujoco.MjModel:
    """The model plus one contact sensor per body (world excluded): number of floor contacts;
    then, per force channel and geom pair, the contact force of that pair (the largest contact's,
    in its contact frame: the normal force first)."""
    spec = mujoco.MjSpec.from_string(mj_xml)
    model = spec.compile()
    for b in range(1, model.nbody):
        s = spec.add_sensor()
        s.type = mujoco.mjtSensor.mjSENS_CONTACT
        s.objtype = mujoco.mjtObj.mjOBJ_BODY
        s.objname = model.body(b).name
        s.reftype = mujoco.mjtObj.mjOBJ_GEOM
        s.refname = floor
        s.intprm[0] = 1  # data: "found" (number of matching contacts)
        s.intprm[1] = 0  # no reduction
        s.intprm[2] = 1  # one slot
        s.dim = 1
    for ch in channels:
        for g1, g2 in ch.pairs:
            s = spec.add_sensor()
            s.type = mujoco.mjtSensor.mjSENS_CONTACT
            s.objtype = mujoco.mjtObj.mjOBJ_GEOM
            s.objname = model.geom(g1).name
            s.reftype = mujoco.mjtObj.mjOBJ_GEOM
            s.refname = model.geom(g2).name
            s.intprm[0] = 1 << int(mujoco.mjtConDataField.mjCONDATA_FORCE)
            s.intprm[1] = 2  # reduce: the contact with the largest force
            s.intprm[2] = 1
            s.dim = 3
    return spec.compile()


class _Pools:
    """``count`` rollout pools of ``nthread`` threads each; a call borrows a free one (a pool
    serves one call at a time), so that as many calls as pools step at once."""

    def __init__(self, nthread: int, count: int):
        from mujoco import rollout

        self.pools = [rollout.Rollout(nthread=nthread) for _ in range(count)]
        self._free: queue.SimpleQueue[int] = queue.SimpleQueue()
        for i in range(count):
            self._free.put(i)

    @contextlib.contextmanager
    def borrow(self):
        """Yields (index, pool) of a free pool, waiting for one."""
        i = self._free.get()
        try:
            yield i, self.pools[i]
        finally:
            self._free.put(i)


@functools.lru_cache(maxsize=8)
def _pools(nthread: int, count: int) -> _Pools:
    return _Pools(nthread, count)


def cpu_count() -> int:
    """CPUs this process may run on (its affinity mask where the OS has one)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


def default_threads() -> int:
    """Threads of one device's pool: the CPUs this process may use over its local devices."""
    return max(1, cpu_count() // jax.local_device_count())


class MujocoPhysics:
    """MuJoCo C stepping of the whole batch inside the compiled loop (see module docstring)."""

    name = "mujoco"

    def __init__(
        self,
        mj_xml: str,
        params_from: mujoco.MjModel,
        model: mjx.Model,
        substeps: int,
        nthread: int | None = None,
        channels=(),
    ):
        self.channels = tuple(channels)
        m = _with_ground_sensors(mj_xml, channels=self.channels)
        # Settings and servo gains come from ``params_from`` (the same structure, maybe edited).
        m.opt.timestep = params_from.opt.timestep
        m.opt.iterations = params_from.opt.iterations
        m.opt.ls_iterations = params_from.opt.ls_iterations
        for f in (
            "actuator_gainprm",
            "actuator_biasprm",
            "actuator_forcerange",
            "dof_damping",
            "dof_armature",
            "geom_friction",
            "body_mass",
        ):
            getattr(m, f)[:] = getattr(params_from, f)
        m.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_AUTORESET)
        WARNINGS.install()
        self.mj = m
        self.model = model
        self.substeps = substeps
        self.nthread = int(nthread or default_threads())
        self.calls = max(1, jax.local_device_count())
        """Calls that may step at once (one per local device), each with its own pool and data."""
        # Scratch data per pool, made here: MjData made inside the callback crashed MuJoCo.
        self._datas = [[mujoco.MjData(m) for _ in range(self.nthread)] for _ in range(self.calls)]
        full = mujoco.mjtState.mjSTATE_FULLPHYSICS
        if mujoco.mj_stateSize(m, full) != 1 + m.nq + m.nv:
            raise NotImplementedError(
                "the MuJoCo C backend supports models without actuator activations, delays or plugins"
            )
        self.nstate = 1 + m.nq + m.nv

    def host_step(self, qpos: np.ndarray, qvel: np.ndarray, warm: np.ndarray, target: np.ndarray):
        """numpy: [..., nq], [..., nv], [..., nv], [..., nu] -> next (qpos, qvel, warm, contacts)."""
        m = self.mj
        lead = qpos.shape[:-1]
        n = int(np.prod(lead)) if lead else 1
        state0 = np.zeros((n, self.nstate), np.float64)
        state0[:, 1 : 1 + m.nq] = qpos.reshape(n, m.nq)
        state0[:, 1 + m.nq :] = qvel.reshape(n, m.nv)
        ctrl = np.repeat(np.asarray(target, np.float64).reshape(n, 1, m.nu), self.substeps, axis=1)
        warm0 = np.ascontiguousarray(warm.reshape(n, m.nv), np.float64)
        with _pools(self.nthread, self.calls).borrow() as (i, pool):
            states, sensors = pool.rollout(
                m, self._datas[i], state0, ctrl, nstep=self.substeps, initial_warmstart=warm0
            )
        last = states[:, -1]
        q1, v1 = last[:, 1 : 1 + m.nq], last[:, 1 + m.nq :]
        v0 = states[:, -2, 1 + m.nq :] if self.substeps > 1 else state0[:, 1 + m.nq :]
        with np.errstate(invalid="ignore", over="ignore"):
            w1 = (v1 - v0) / m.opt.timestep
        w1 = np.where(np.isfinite(w1), w1, 0.0)
        nb = m.nbody - 1
        touch = sensors[:, -1, :nb] > 0
        f32 = lambda x, d: np.asarray(x, np.float32).reshape(lead + (d,))
        forces = np.zeros((n, len(self.channels)), np.float64)
        i = nb
        for c, ch in enumerate(self.channels):
            k = len(ch.pairs)
            normal = sensors[:, :, i : i + 3 * k : 3]  # [n, substeps, pairs]
            forces[:, c] = normal.sum(-1).max(-1)
            i += 3 * k
        return (
            f32(q1, m.nq),
            f32(v1, m.nv),
            f32(w1, m.nv),
            touch.reshape(lead + (nb,)),
            f32(forces, len(self.channels)),
        )

    def step(self, data: mjx.Data, target: jax.Array) -> tuple[mjx.Data, jax.Array]:
        """Holds ``target`` for ``substeps`` MuJoCo C steps; returns (data, body ground contacts).

        The contacts are read by sensors in the last step's forward pass (one substep old, as
        MJX's)."""
        return self.step_forces(data, target)[:2]

    def step_forces(self, data: mjx.Data, target: jax.Array) -> tuple[mjx.Data, jax.Array, jax.Array]:
        """As ``step``, plus [n_channels] the maximum over the substeps of each force channel."""
        m = self.mj
        lead = data.qpos.shape[:-1]
        shapes = (
            jax.ShapeDtypeStruct(lead + (m.nq,), jnp.float32),
            jax.ShapeDtypeStruct(lead + (m.nv,), jnp.float32),
            jax.ShapeDtypeStruct(lead + (m.nv,), jnp.float32),
            jax.ShapeDtypeStruct(lead + (m.nbody - 1,), jnp.bool_),
            jax.ShapeDtypeStruct(lead + (len(self.channels),), jnp.float32),
        )
        qpos, qvel, warm, touch, forces = jax.pure_callback(
            self.host_step,
            shapes,
            data.qpos,
            data.qvel,
            data.qacc_warmstart,
            target.astype(jnp.float32),
            vmap_method="broadcast_all",
        )
        data = data.replace(
            qpos=qpos, qvel=qvel, qacc_warmstart=warm, ctrl=target, time=data.time + self.substeps * m.opt.timestep
        )
        return data, touch, forces


def make_physics(
    backend: str,
    mj: mujoco.MjModel,
    mj_xml: str,
    model: mjx.Model,
    substeps: int,
    nthread: int | None = None,
    channels=(),
):
    """The backend object for a resolved or ``auto`` backend name; ``channels``: the force
    channels ``step_forces`` reports (``physics/arena.py``)."""
    name = resolve_backend(backend)
    if name == "mjx":
        return MJXPhysics(mj, model, substeps, channels)
    return MujocoPhysics(mj_xml, mj, model, substeps, nthread, channels)
