"""Explicit 4-wide vector operations for the pair passes (numba intrinsics).

LLVM does not vectorise the gathers of :mod:`granpipe.engine.kernels` (the pair indices
are data, and numba leaves LLVM's SLP vectoriser off by default since it miscompiled
code: numba PR #8852, issues #8705 and #8681), so a scalar gather costs eight loads,
four subtractions and four stores per pair. :func:`gather4` takes four listed pairs at
once: per pair and field (positions, velocities) one two-wide load from each disk's
``(x, y)`` in the flat ``2N`` row and one subtraction, the lanes combined in registers
and stored as row vectors. On the drum pile (Intel core of docs/engine_performance.md,
round 5) it takes 1.8 ns per pair, against 4.3 for one four-wide subtraction per pair
from copied per-disk records ``[x, y, vx, vy]`` with lane stores, and 2.9 for those
records with four pairs' differences transposed in registers (the copy into the
records cost more than the loads it saved). Lane by lane the arithmetic is the IEEE
arithmetic of the scalar code, so results are bit-identical.

Numba's own on-disk cache keys a kernel on its own source file only; the package's
locator (:mod:`granpipe._jit`) keys every kernel on all jitted sources, this module
included, so an edit here recompiles the kernels that use it in the next process.
"""

from __future__ import annotations

import types as pytypes

from llvmlite import ir
from numba.core import cgutils, types
from numba.extending import intrinsic

from granpipe.engine.layout import B_DELTA, B_DVX, B_DVY, B_E0, B_INV_R, B_NX, B_NY

__all__ = [
    "gather4",
    "gather4_spins",
    "gather4_spins_tail",
    "gather4_tail",
    "kick8",
    "kick8_first",
    "kick8_v2",
    "speed2_lanes",
    "tangent8",
    "tangent8_first",
    "tangent8_last",
]

_F64 = ir.DoubleType()
_V4 = ir.VectorType(_F64, 4)
_V2 = ir.VectorType(_F64, 2)
_I64 = ir.IntType(64)
_I32 = ir.IntType(32)


def _f64_vectors(*arrays):
    return all(
        isinstance(a, types.Array) and a.ndim == 1 and a.dtype == types.float64 for a in arrays
    )


def _vec_at(builder, data, idx, lanes):
    """Pointer to ``lanes`` consecutive doubles of ``data`` from element ``idx``."""
    vt = ir.VectorType(_F64, lanes)
    return builder.bitcast(builder.gep(data, [idx]), vt.as_pointer())


@intrinsic
def speed2_lanes(typingctx, v, f, im, mob, h, m):
    """Four partial sums of ``|v + h F/m|²`` over mobile components: lane ``c`` is
    ``sum_k (u_k * u_k) * mob_k`` for ``k = c, c + 4, ... < m`` in increasing ``k``, with
    ``u_k = v_k + h * (f_k * im_k)`` (``m`` a multiple of 4; the caller adds the rest).

    The four running sums of :func:`granpipe.engine.kernels._v2`, the same IEEE
    operations in the same order, held in one ``<4 x double>``: LLVM does not vectorise
    the four scalar sums (its SLP vectoriser is off in numba), and they ran at three
    cycles per component.
    """
    if not _f64_vectors(v, f, im, mob):
        return None
    ret = types.UniTuple(types.float64, 4)
    sig = ret(v, f, im, mob, h, m)

    def codegen(context, builder, signature, args):
        va, fa, ia, ma = (
            context.make_array(t)(context, builder, x)
            for t, x in zip(sig.args[:4], args[:4], strict=True)
        )
        hv = _bcast(builder, args[4], 4)
        m = context.cast(builder, args[5], sig.args[5], types.intp)
        groups = builder.udiv(m, ir.Constant(_I64, 4))
        acc = cgutils.alloca_once_value(builder, ir.Constant(_V4, [0.0] * 4))
        with cgutils.for_range(builder, groups) as loop:
            k = builder.mul(loop.index, ir.Constant(_I64, 4))
            vk, fk, ik, mk = (
                builder.load(_vec_at(builder, x.data, k, 4), align=8) for x in (va, fa, ia, ma)
            )
            u = builder.fadd(vk, builder.fmul(hv, builder.fmul(fk, ik)))
            builder.store(
                builder.fadd(builder.load(acc), builder.fmul(builder.fmul(u, u), mk)), acc
            )
        total = builder.load(acc)
        lanes = [builder.extract_element(total, ir.Constant(_I32, c)) for c in range(4)]
        return context.make_tuple(builder, ret, lanes)

    return sig, codegen


# ------------------------------------------------------------ per-disk passes (8 wide)

_V8 = ir.VectorType(_F64, 8)
_I64x4 = ir.VectorType(_I64, 4)
_I64x8 = ir.VectorType(_I64, 8)
# a half-step velocity is bad unless |w| < BIG (kernels._BIG is this one)
BIG = 1e300


def _bcast(builder, x, lanes):
    """The scalar ``x`` in every lane of a ``lanes``-wide vector."""
    vt = ir.VectorType(x.type, lanes)
    v = builder.insert_element(ir.Constant(vt, ir.Undefined), x, ir.Constant(_I32, 0))
    return builder.shuffle_vector(v, v, ir.Constant(ir.VectorType(_I32, lanes), [0] * lanes))


def _pick(builder, x, idx):
    """Lanes ``idx`` of the vector ``x``."""
    return builder.shuffle_vector(x, x, ir.Constant(ir.VectorType(_I32, len(idx)), idx))


def _xy(builder, x8):
    """Eight flat components ``[x0, y0, .., x3, y3]`` of four disks -> ``[x0..x3], [y0..y3]``."""
    return _pick(builder, x8, [0, 2, 4, 6]), _pick(builder, x8, [1, 3, 5, 7])


def _hsum(builder, v, lanes):
    """Sum of the lanes of an integer vector (i64)."""
    t = builder.extract_element(v, ir.Constant(_I32, 0))
    for c in range(1, lanes):
        t = builder.add(t, builder.extract_element(v, ir.Constant(_I32, c)))
    return t


def _accumulate(builder, cell, x):
    builder.store(builder.add(builder.load(cell), x), cell)


def _fadd_into(builder, cell, x):
    builder.store(builder.fadd(builder.load(cell), x), cell)


def _arrays(context, builder, sig, args, count):
    return [
        context.make_array(t)(context, builder, x)
        for t, x in zip(sig.args[:count], args[:count], strict=True)
    ]


def _kick8(finish, want_v2):
    """Intrinsic ``(p, v, f, im, mob, b, h, dt, thr2, m) -> (s0, s1, s2, s3, bad, moved)``:
    the per-disk pass of a step (:func:`granpipe.engine.kernels._kick_drift`) over the
    flat ``2N`` rows, components ``k < m`` (``m`` a multiple of 8), four disks (eight
    components, one 8-wide vector) a group.

    Per component ``a = h (f im)``; with ``finish`` the previous step's pending second
    half kick ``u = v + a``, then the first half kick ``w = u + a`` (without, ``w = v +
    a``), the drift ``p += dt w`` and ``v = w``. Returns the four running sums of ``(u u)
    mob`` (lane ``c`` over ``k = c mod 4`` in increasing ``k``: the sums of
    :func:`speed2_lanes`; zero unless ``want_v2``), the count of components with ``not |w|
    < 1e300`` (with ``finish``), and of disks with ``|p - b|² > thr2``. The IEEE operations
    of the scalar loops in their order, so the same bits, in one pass over the rows
    instead of three (kick and drift, displacement test, ``v2``).
    """

    def typer(typingctx, p, v, f, im, mob, b, h, dt, thr2, m):
        if not _f64_vectors(p, v, f, im, mob, b):
            return None
        ret = types.Tuple((types.float64,) * 4 + (types.int64, types.int64))
        sig = ret(p, v, f, im, mob, b, h, dt, thr2, m)

        def codegen(context, builder, signature, args):
            pa, va, fa, ia, ma, ba = _arrays(context, builder, sig, args, 6)
            h8, dt8 = (_bcast(builder, args[c], 8) for c in (6, 7))
            thr = _bcast(builder, args[8], 4)
            big = ir.Constant(_V8, [BIG] * 8)
            m = context.cast(builder, args[9], sig.args[9], types.intp)
            acc = cgutils.alloca_once_value(builder, ir.Constant(_V4, [0.0] * 4))
            bad = cgutils.alloca_once_value(builder, ir.Constant(_I64x8, [0] * 8))
            moved = cgutils.alloca_once_value(builder, ir.Constant(_I64x4, [0] * 4))
            with cgutils.for_range(builder, builder.udiv(m, ir.Constant(_I64, 8))) as loop:
                k = builder.mul(loop.index, ir.Constant(_I64, 8))
                pp, vp, fp, ip, mp, bp = (
                    _vec_at(builder, x.data, k, 8) for x in (pa, va, fa, ia, ma, ba)
                )
                fim = builder.fmul(builder.load(fp, align=8), builder.load(ip, align=8))
                a = builder.fmul(h8, fim)
                u = builder.fadd(builder.load(vp, align=8), a)
                if want_v2:
                    c = builder.fmul(builder.fmul(u, u), builder.load(mp, align=8))
                    for half in ([0, 1, 2, 3], [4, 5, 6, 7]):
                        _fadd_into(builder, acc, _pick(builder, c, half))
                w = builder.fadd(u, a) if finish else u
                builder.store(w, vp, align=8)
                pn = builder.fadd(builder.load(pp, align=8), builder.fmul(dt8, w))
                builder.store(pn, pp, align=8)
                if finish:
                    aw = _call(builder, "llvm.fabs.v8f64", [w])
                    # not |w| < 1e300, NaN included
                    nb = builder.fcmp_unordered(">=", aw, big)
                    _accumulate(builder, bad, builder.zext(nb, _I64x8))
                dx, dy = _xy(builder, builder.fsub(pn, builder.load(bp, align=8)))
                r2 = builder.fadd(builder.fmul(dx, dx), builder.fmul(dy, dy))
                _accumulate(
                    builder, moved, builder.zext(builder.fcmp_ordered(">", r2, thr), _I64x4)
                )
            total = builder.load(acc)
            out = [builder.extract_element(total, ir.Constant(_I32, c)) for c in range(4)]
            out += [_hsum(builder, builder.load(bad), 8), _hsum(builder, builder.load(moved), 4)]
            return context.make_tuple(builder, ret, out)

        return sig, codegen

    return intrinsic(typer)


kick8_first = _kick8(False, False)
kick8 = _kick8(True, False)
kick8_v2 = _kick8(True, True)


def _tangent8(mode):
    """Intrinsic ``(tr, tv, tf, im, mob, prev, contacts, h, dt, n) -> 12 sums``: the
    tangent vector's per-disk pass (:func:`granpipe.engine.kernels._tangent_pass`) over
    the disks ``i < n`` (``n`` a multiple of 4), four disks (one 8-wide vector of flat
    components) a group.

    Per component ``a = h (tf im)``. ``mode`` 0: the first half kick and drift, ``tv +=
    a``, ``tr += dt tv``. Modes 1 and 2 first finish the previous step: its second half
    kick ``u = tv + a`` and, per disk, its squared norm ``q_i = (((tr_x² + tr_y²) + u_x²) +
    u_y²) mob_i`` (the order of the scalar code); with ``s_i = contacts_i >= 2`` they sum
    ``q_i`` over S, the stored ``prev_i`` over S and ``q_i`` over all disks, and set
    ``prev_i = q_i``. Mode 1 then kicks and drifts (``tv = u + a``, ``tr += dt tv``); mode
    2 (the end of a run) leaves ``tv = u``. Each sum comes as four lanes (lane ``c`` over
    the disks ``i = c mod 4``): ``(num0..3, den0..3, total0..3)``, zero in mode 0.
    """

    def typer(typingctx, tr, tv, tf, im, mob, prev, contacts, h, dt, n):
        if not _f64_vectors(tr, tv, tf, im, mob, prev):
            return None
        ret = types.UniTuple(types.float64, 12)
        sig = ret(tr, tv, tf, im, mob, prev, contacts, h, dt, n)

        def codegen(context, builder, signature, args):
            ra, va, fa, ia, ma, qa, ca = _arrays(context, builder, sig, args, 7)
            h8, dt8 = (_bcast(builder, args[c], 8) for c in (7, 8))
            n = context.cast(builder, args[9], sig.args[9], types.intp)
            zero = ir.Constant(_V4, [0.0] * 4)
            two = ir.Constant(_I64x4, [2] * 4)
            accs = [cgutils.alloca_once_value(builder, zero) for _ in range(3)]
            with cgutils.for_range(builder, builder.udiv(n, ir.Constant(_I64, 4))) as loop:
                i = builder.mul(loop.index, ir.Constant(_I64, 4))
                k = builder.mul(i, ir.Constant(_I64, 2))
                rp, vp, fp, ip, mp = (_vec_at(builder, x.data, k, 8) for x in (ra, va, fa, ia, ma))
                fim = builder.fmul(builder.load(fp, align=8), builder.load(ip, align=8))
                a = builder.fmul(h8, fim)
                u = builder.fadd(builder.load(vp, align=8), a)
                r = builder.load(rp, align=8)
                if mode != 0:
                    rx, ry = _xy(builder, r)
                    ux, uy = _xy(builder, u)
                    mx, _ = _xy(builder, builder.load(mp, align=8))
                    q = builder.fadd(builder.fmul(rx, rx), builder.fmul(ry, ry))
                    q = builder.fadd(q, builder.fmul(ux, ux))
                    q = builder.fmul(builder.fadd(q, builder.fmul(uy, uy)), mx)
                    cp = builder.bitcast(builder.gep(ca.data, [i]), _I64x4.as_pointer())
                    s = builder.icmp_signed(">=", builder.load(cp, align=8), two)
                    pp = _vec_at(builder, qa.data, i, 4)
                    old = builder.load(pp, align=8)
                    builder.store(q, pp, align=8)
                    terms = (builder.select(s, q, zero), builder.select(s, old, zero), q)
                    for acc, x in zip(accs, terms, strict=True):
                        _fadd_into(builder, acc, x)
                if mode == 2:
                    builder.store(u, vp, align=8)
                else:
                    w = u if mode == 0 else builder.fadd(u, a)
                    builder.store(w, vp, align=8)
                    builder.store(builder.fadd(r, builder.fmul(dt8, w)), rp, align=8)
            out = []
            for acc in accs:
                tot = builder.load(acc)
                out += [builder.extract_element(tot, ir.Constant(_I32, c)) for c in range(4)]
            return context.make_tuple(builder, ret, out)

        return sig, codegen

    return intrinsic(typer)


tangent8_first = _tangent8(0)
tangent8 = _tangent8(1)
tangent8_last = _tangent8(2)


# --------------------------------------------------------------------------- lanes DSL


class _Mask:
    """Four lanes of a comparison result (``<4 x i1>``)."""

    __slots__ = ("b", "v")

    def __init__(self, b, v):
        self.b = b
        self.v = v

    def __and__(self, o):
        return _Mask(self.b, self.b.and_(self.v, o.v))

    def __or__(self, o):
        return _Mask(self.b, self.b.or_(self.v, o.v))

    def __bool__(self):
        raise TypeError("a contact law run on four lanes may not branch on a lane value")


class _Lanes:
    """Four float64 lanes (``<4 x double>``) with the IEEE arithmetic of Python floats."""

    __slots__ = ("b", "v")

    def __init__(self, b, v):
        self.b = b
        self.v = v

    def _of(self, o):
        if isinstance(o, _Lanes):
            return o.v
        if isinstance(o, (int, float)) and not isinstance(o, bool):
            return ir.Constant(_V4, [float(o)] * 4)
        raise TypeError(f"cannot combine four lanes with {type(o).__name__}")

    def _op(self, name, a, c):
        return _Lanes(self.b, getattr(self.b, name)(a, c))

    def __add__(self, o):
        return self._op("fadd", self.v, self._of(o))

    def __radd__(self, o):
        return self._op("fadd", self._of(o), self.v)

    def __sub__(self, o):
        return self._op("fsub", self.v, self._of(o))

    def __rsub__(self, o):
        return self._op("fsub", self._of(o), self.v)

    def __mul__(self, o):
        return self._op("fmul", self.v, self._of(o))

    def __rmul__(self, o):
        return self._op("fmul", self._of(o), self.v)

    def __truediv__(self, o):
        return self._op("fdiv", self.v, self._of(o))

    def __rtruediv__(self, o):
        return self._op("fdiv", self._of(o), self.v)

    def __neg__(self):
        return _Lanes(self.b, self.b.fneg(self.v))

    def __abs__(self):
        return _Lanes(self.b, _call(self.b, "llvm.fabs.v4f64", [self.v]))

    def _cmp(self, op, o):
        return _Mask(self.b, self.b.fcmp_ordered(op, self.v, self._of(o)))

    def __lt__(self, o):
        return self._cmp("<", o)

    def __le__(self, o):
        return self._cmp("<=", o)

    def __gt__(self, o):
        return self._cmp(">", o)

    def __ge__(self, o):
        return self._cmp(">=", o)

    def __eq__(self, o):
        return self._cmp("==", o)

    __hash__ = None


def _call(b, name, args):
    """Call the LLVM intrinsic ``name`` on vectors of one type (the result's too)."""
    vt = args[0].type
    fnty = ir.FunctionType(vt, [vt] * len(args))
    fn = b.module.globals.get(name) or ir.Function(b.module, fnty, name=name)
    return b.call(fn, args)


def _select(c, a, x):
    """``a if c else x`` on lanes (both sides are evaluated: the laws have no side effects)."""
    if not isinstance(c, _Mask):
        raise TypeError("a lane select needs a lane comparison")
    ref = a if isinstance(a, _Lanes) else x
    if not isinstance(ref, _Lanes):
        ref = _Lanes(c.b, ir.Constant(_V4, [0.0] * 4))
    return _Lanes(c.b, c.b.select(c.v, ref._of(a), ref._of(x)))


def lanes_of(fn):
    """The scalar law ``fn`` (a jitted leaf of :mod:`granpipe.engine.laws`) run on four lanes.

    The leaf's own code object is called with its global ``select``
    (:func:`granpipe.engine.contract.select`) bound to a lane select: the vector kernels
    evaluate the very expressions of the scalar law, in the same order, so lane by lane
    they give the same bits. A leaf that branches on a value (``if``, ``a if c else x``)
    cannot run on lanes: the lane comparison refuses to be a truth value.
    """
    py = getattr(fn, "py_func", fn)
    env = dict(py.__globals__)
    env["select"] = _select
    return pytypes.FunctionType(py.__code__, env, py.__name__, py.__defaults__, py.__closure__)


# --------------------------------------------------------------------------- pair frames


class _Frame:
    """Code generation for four consecutive listed pairs ``k .. k+3`` inside an intrinsic.

    ``full`` groups use vector loads and stores of the pair arrays; the last, partial
    group (``nvalid < 4`` pairs) loads through clamped indices and stores lane by lane.
    """

    def __init__(self, context, builder, sig, args, names, full):
        self.b = builder
        self.full = full
        self.a = {}
        self.val = {}
        for name, ty, val in zip(names, sig.args, args, strict=False):
            if isinstance(ty, types.Array):
                self.a[name] = context.make_array(ty)(context, builder, val)
            else:
                self.val[name] = context.cast(builder, val, ty, types.intp)
        k = self.val["k"]
        self.k = [builder.add(k, ir.Constant(_I64, lane)) for lane in range(4)]
        if not full:
            nv = self.val["nvalid"]
            self.valid = [
                builder.icmp_signed("<", ir.Constant(_I64, lane), nv) for lane in range(4)
            ]
            self.k = [builder.select(v, kl, k) for v, kl in zip(self.valid, self.k, strict=True)]

    def ptr(self, name, idx):
        return self.b.gep(self.a[name].data, [idx])

    def scalar(self, name, idx):
        p = self.ptr(name, idx)
        elem = p.type.pointee
        align = elem.width // 8 if isinstance(elem, ir.IntType) else 8
        return self.b.load(p, align=align)

    def index(self, name):
        """The four pair indices ``name[k + lane]`` as i64."""
        return [self.b.zext(self.scalar(name, kl), _I64) for kl in self.k]

    def _at(self, off):
        if off is None:
            return self.k
        return [self.b.add(kl, off) for kl in self.k]

    def size(self, name):
        """Length of the 1-D array argument ``name`` (i64)."""
        return self.b.extract_value(self.a[name].shape, 0)

    def row(self, r):
        """Offset of row ``r`` of a flat (rows, cap) array (``cap`` an argument)."""
        return self.b.mul(ir.Constant(_I64, r), self.val["cap"])

    def lanes(self, name, off=None, elem=_F64):
        """``name[off + k .. off + k+3]`` as four lanes."""
        at = self._at(off)
        vt = ir.VectorType(elem, 4)
        if self.full:
            p = self.b.bitcast(self.ptr(name, at[0]), vt.as_pointer())
            v = self.b.load(p, align=8)
        else:
            v = ir.Constant(vt, ir.Undefined)
            for lane, kl in enumerate(at):
                v = self.b.insert_element(v, self.scalar(name, kl), ir.Constant(_I32, lane))
        return _Lanes(self.b, v) if elem is _F64 else v

    def splat(self, name, i):
        return _Lanes(self.b, _bcast(self.b, self.scalar(name, ir.Constant(_I64, i)), 4))

    def _diffs(self, name, i, j, vt):
        """Per pair, ``name[w i .. w i + w-1] - name[w j .. w j + w-1]`` as one vector of
        type ``vt`` (``w`` lanes): one load from each disk's run of ``w`` values."""
        b = self.b
        w = ir.Constant(_I64, vt.count)
        d = []
        for il, jl in zip(i, j, strict=True):
            pa = b.bitcast(self.ptr(name, b.mul(il, w)), vt.as_pointer())
            pb = b.bitcast(self.ptr(name, b.mul(jl, w)), vt.as_pointer())
            d.append(b.fsub(b.load(pa, align=8), b.load(pb, align=8)))
        return d

    def xy_diff(self, name, i, j):
        """``name[2i:2i+2] - name[2j:2j+2]`` of the four pairs (a flat ``2N`` per-disk row),
        as two lane vectors ``(dx, dy)``: one two-wide load and subtraction per disk."""
        b = self.b
        d = self._diffs(name, i, j, _V2)
        m4 = ir.VectorType(_I32, 4)
        lo = b.shuffle_vector(d[0], d[1], ir.Constant(m4, [0, 1, 2, 3]))
        hi = b.shuffle_vector(d[2], d[3], ir.Constant(m4, [0, 1, 2, 3]))
        return [
            _Lanes(b, b.shuffle_vector(lo, hi, ir.Constant(m4, [c, c + 2, c + 4, c + 6])))
            for c in (0, 1)
        ]

    def mask_i64(self, m):
        """A lane mask as ``<4 x i64>`` 0/1 (lanes past the last valid pair cleared)."""
        v = m.v
        if not self.full:
            for lane in range(4):
                at = ir.Constant(_I32, lane)
                bit = self.b.and_(self.b.extract_element(v, at), self.valid[lane])
                v = self.b.insert_element(v, bit, at)
        return self.b.zext(v, ir.VectorType(_I64, 4))

    def count(self, m64):
        return _hsum(self.b, m64, 4)

    def store_lanes(self, name, v, off=None):
        """``name[off + k .. off + k+3] = v`` (lanes or an integer vector)."""
        b = self.b
        at = self._at(off)
        if isinstance(v, _Lanes):
            v = v.v
        if self.full:
            b.store(v, b.bitcast(self.ptr(name, at[0]), v.type.as_pointer()), align=8)
            return
        for lane in range(4):
            with b.if_then(self.valid[lane]):
                b.store(
                    b.extract_element(v, ir.Constant(_I32, lane)),
                    self.ptr(name, at[lane]),
                    align=8,
                )

    def scatter_pairs(self, i, j, prev, sums):
        """Add pair vectors to per-disk (flat ``2N``) arrays, lane by lane in list order.

        ``sums`` lists ``(name, x, y, acc)``: ``name[2j:2j+2] -= (x, y)`` goes to memory
        at once; the owner's share is added to the running sum ``acc`` (``<2 x double>``)
        of owner ``prev``, which goes to memory only when the owner changes (consecutive
        pairs share the owner; adding each to memory would chain loads on stores). This is
        the order of ``kernels._scatter``. Returns the new ``prev`` and sums.
        """
        b = self.b
        m4 = ir.VectorType(_I32, 4)
        two = ir.Constant(_I64, 2)
        zero2 = ir.Constant(_V2, [0.0, 0.0])
        halves = []
        for _name, x, y, _acc in sums:
            lo = b.shuffle_vector(x.v, y.v, ir.Constant(m4, [0, 4, 1, 5]))
            hi = b.shuffle_vector(x.v, y.v, ir.Constant(m4, [2, 6, 3, 7]))
            halves.append((lo, hi))
        accs = [acc for _name, _x, _y, acc in sums]

        def rmw(name, idx, op, x):
            p = b.bitcast(self.ptr(name, b.mul(idx, two)), _V2.as_pointer())
            b.store(getattr(b, op)(b.load(p, align=8), x), p, align=8)

        for lane in range(4):
            sel = ir.Constant(ir.VectorType(_I32, 2), [0, 1] if lane % 2 == 0 else [2, 3])
            pairs = [b.shuffle_vector(h[lane // 2], h[lane // 2], sel) for h in halves]
            new_owner = b.icmp_unsigned("!=", i[lane], prev)
            if not self.full:
                new_owner = b.and_(new_owner, self.valid[lane])
            with b.if_then(new_owner):
                for (name, *_), acc in zip(sums, accs, strict=True):
                    rmw(name, prev, "fadd", acc)
            summed = [
                b.fadd(b.select(new_owner, zero2, acc), x)
                for acc, x in zip(accs, pairs, strict=True)
            ]
            if self.full:
                for (name, *_), x in zip(sums, pairs, strict=True):
                    rmw(name, j[lane], "fsub", x)
                accs = summed
                prev = i[lane]
            else:
                with b.if_then(self.valid[lane]):
                    for (name, *_), x in zip(sums, pairs, strict=True):
                        rmw(name, j[lane], "fsub", x)
                accs = [
                    b.select(self.valid[lane], a, acc) for a, acc in zip(summed, accs, strict=True)
                ]
                prev = b.select(self.valid[lane], i[lane], prev)
        return prev, accs


def _sqrt(x):
    return _Lanes(x.b, _call(x.b, "llvm.sqrt.v4f64", [x.v]))


# rows of the pair buffer (kernels.B_*) through which the two halves of a pair pass talk


@intrinsic
def touch_bits4(typingctx, pos, pi, pj, k, ssum):
    """``sum over lanes c of 2**c`` for the listed pairs ``k .. k+3`` that are not apart,
    i.e. ``not (dx² + dy² > ssum²)`` with ``(dx, dy)`` from the flat ``2N`` positions
    ``pos`` (the test, and its treatment of NaN, of the scalar compaction in
    :func:`granpipe.engine.kernels._gather_compact`; the same IEEE operations). Zero when
    all four are apart: the compacted gather skips such groups without a branch per pair.
    """
    sig = types.int64(pos, pi, pj, k, ssum)

    def codegen(context, builder, signature, args):
        fr = _Frame(context, builder, signature, args, ("pos", "pi", "pj", "k", "ssum"), True)
        dx, dy = fr.xy_diff("pos", fr.index("pi"), fr.index("pj"))
        s = fr.lanes("ssum")
        apart = dx * dx + dy * dy > s * s
        bits = builder.bitcast(apart.v, ir.IntType(4))
        return builder.zext(builder.xor(bits, ir.Constant(ir.IntType(4), 15)), _I64)

    return sig, codegen


_GATHER_ARGS = ("p", "v", "pi", "pj", "k", "nvalid", "rows", "cap", "off", "w", "woff")


def _gather4(full, spins):
    """Intrinsic ``(p, v, pi, pj, k, nvalid, rows, cap, off[, w, woff]) -> None``: for the
    listed pairs ``k' = k .. k+nvalid-1``, the relative positions and velocities into four
    rows, ``rows[off + c*cap + k']`` = ``p[2i + c] - p[2j + c]`` (c = 0, 1) and
    ``v[2i + c-2] - v[2j + c-2]`` (c = 2, 3), with ``i, j = pi[k'], pj[k']`` and ``p, v``
    flat ``2N`` rows: one two-wide load and subtraction per disk and field
    (:meth:`_Frame.xy_diff`), four pairs' lanes stored as vectors. With ``spins``, also
    the two spins ``w[i]``, ``w[j]`` into ``rows[woff + k']`` and ``rows[woff + cap + k']``.
    """

    def codegen(context, builder, signature, args):
        fr = _Frame(context, builder, signature, args, _GATHER_ARGS, full)
        i = fr.index("pi")
        j = fr.index("pj")
        diffs = fr.xy_diff("p", i, j) + fr.xy_diff("v", i, j)
        for c, val in enumerate(diffs):
            fr.store_lanes("rows", val, builder.add(fr.val["off"], fr.row(c)))
        if spins:
            for c, idx in enumerate((i, j)):
                lanes = ir.Constant(_V4, ir.Undefined)
                for lane, il in enumerate(idx):
                    x = fr.scalar("w", il)
                    lanes = builder.insert_element(lanes, x, ir.Constant(_I32, lane))
                at = builder.add(fr.val["woff"], fr.row(c))
                fr.store_lanes("rows", _Lanes(builder, lanes), at)
        return context.get_dummy_value()

    if spins:

        def typer(typingctx, p, v, pi, pj, k, nvalid, rows, cap, off, w, woff):
            return types.void(p, v, pi, pj, k, nvalid, rows, cap, off, w, woff), codegen

    else:

        def typer(typingctx, p, v, pi, pj, k, nvalid, rows, cap, off):
            return types.void(p, v, pi, pj, k, nvalid, rows, cap, off), codegen

    return intrinsic(typer)


gather4 = _gather4(True, False)
gather4_tail = _gather4(False, False)
gather4_spins = _gather4(True, True)
gather4_spins_tail = _gather4(False, True)


_FRONT_ARGS = (
    "p",
    "v",
    "tp",
    "tv",
    "pi",
    "pj",
    "k",
    "nvalid",
    "ssum",
    "slim",
    "touch",
    "rows",
    "cap",
)


def _pair_front4(full):
    """Intrinsic ``(p, v, tp, tv, pi, pj, k, nvalid, ssum, slim, touch, rows, cap) -> code``:
    the geometric half of a pair pass for the listed pairs ``k .. k+nvalid-1``.

    From the flat ``2N`` positions ``p`` and velocities ``v`` (as :func:`gather4`) it
    forms the relative position and velocity, ``r``, ``1/r``, the unit normal and
    ``delta = r - (a_i + a_j)``, and writes them to rows of the flat pair buffer ``rows``
    (row length ``cap``) for :func:`_drum_back4`; with ``tp`` non-empty (the tangent
    vector's position and velocity parts ``tp, tv``) also the relative tangent vector.
    It stores the touch flags (``r² <= (a_i + a_j)²``) and returns ``touching + 8 deep +
    64 changed``: the counts of touching pairs and of pairs deeper than their bound
    ``slim``, and the lanes whose touch flag changed (bit ``c`` for pair ``k + c``).
    """

    def typer(typingctx, p, v, tp, tv, pi, pj, k, nvalid, ssum, slim, touch, rows, cap):
        sig = types.int64(p, v, tp, tv, pi, pj, k, nvalid, ssum, slim, touch, rows, cap)

        def codegen(context, builder, signature, args):
            fr = _Frame(context, builder, signature, args, _FRONT_ARGS, full)
            i = fr.index("pi")
            j = fr.index("pj")
            dx, dy = fr.xy_diff("p", i, j)
            dvx, dvy = fr.xy_diff("v", i, j)
            s = fr.lanes("ssum")
            lim = fr.lanes("slim")
            r2 = dx * dx + dy * dy
            r = _sqrt(r2)
            inv_r = 1.0 / r
            delta = r - s
            t64 = fr.mask_i64(r2 <= s * s)
            old = fr.lanes("touch", elem=_I64)
            ch = fr.mask_i64(_Mask(builder, builder.icmp_unsigned("!=", old, t64)))
            changed = builder.extract_element(ch, ir.Constant(_I32, 0))
            for lane in range(1, 4):
                bit = builder.extract_element(ch, ir.Constant(_I32, lane))
                changed = builder.or_(changed, builder.shl(bit, ir.Constant(_I64, lane)))
            fr.store_lanes("touch", t64)
            bad = fr.count(fr.mask_i64(-delta > lim))
            out = [(B_NX, dx * inv_r), (B_NY, dy * inv_r), (B_DVX, dvx), (B_DVY, dvy)]
            out += [(B_DELTA, delta), (B_INV_R, inv_r)]
            for row, v in out:
                fr.store_lanes("rows", v, fr.row(row))
            with builder.if_then(builder.icmp_signed(">", fr.size("tp"), ir.Constant(_I64, 0))):
                e = fr.xy_diff("tp", i, j) + fr.xy_diff("tv", i, j)
                for c, val in enumerate(e):
                    fr.store_lanes("rows", val, fr.row(B_E0 + c))
            code = builder.add(fr.count(t64), builder.mul(bad, ir.Constant(_I64, 8)))
            return builder.add(code, builder.mul(changed, ir.Constant(_I64, 64)))

        return sig, codegen

    return intrinsic(typer)


_BACK_ARGS = ("rows", "cap", "k", "nvalid", "f", "tf", "pi", "pj", "touch", "law", "prev")


def _drum_back4(full, tangent):
    """Intrinsic ``(rows, cap, k, nvalid, f, tf, pi, pj, touch, law, prev, ax, ay, bx, by)
    -> (prev, ax, ay, bx, by)``: the drum law (:func:`granpipe.engine.laws.drum_force`,
    and with ``tangent`` its derivative ``drum_force_jvp`` along the tangent vector) on
    the pairs ``k .. k+nvalid-1`` from the rows :func:`_pair_front4` wrote, zero where
    the touch flag is off, added to the forces ``f`` (and perturbations ``tf``), flat
    ``2N``. ``prev`` and the ``a``/``b`` pairs are the running owner sums of
    :meth:`_Frame.scatter_pairs`; the caller starts them at the first owner and zero, and
    adds the last sums to that owner's row when the pass ends.
    """
    from granpipe.engine.laws import drum_force, drum_force_jvp

    force4 = lanes_of(drum_force)
    jvp4 = lanes_of(drum_force_jvp)

    def typer(typingctx, rows, cap, k, nvalid, f, tf, pi, pj, touch, law, prev, ax, ay, bx, by):
        ret = types.Tuple((types.int64,) + (types.float64,) * 4)
        sig = ret(rows, cap, k, nvalid, f, tf, pi, pj, touch, law, prev, ax, ay, bx, by)

        def codegen(context, builder, signature, args):
            fr = _Frame(context, builder, signature, args, _BACK_ARGS, full)
            rows = (B_NX, B_NY, B_DVX, B_DVY, B_DELTA, B_INV_R)
            nx, ny, dvx, dvy, delta, inv_r = (fr.lanes("rows", fr.row(r)) for r in rows)
            par = [fr.splat("law", c) for c in range(4)]
            fx, fy, f_n, f_t, regime = force4(nx, ny, delta, dvx, dvy, *par)
            zero = ir.Constant(ir.VectorType(_I64, 4), [0] * 4)
            t = _Mask(builder, builder.icmp_unsigned("!=", fr.lanes("touch", elem=_I64), zero))
            sums = [("f", _select(t, fx, 0.0), _select(t, fy, 0.0))]
            if tangent:
                e = [fr.lanes("rows", fr.row(B_E0 + c)) for c in range(4)]
                gx, gy = jvp4(nx, ny, inv_r, dvx, dvy, f_n, f_t, regime, *e, *par)
                sums.append(("tf", _select(t, gx, 0.0), _select(t, gy, 0.0)))
            sums = [
                (name, x, y, _pack2(builder, args[11 + 2 * q], args[12 + 2 * q]))
                for q, (name, x, y) in enumerate(sums)
            ]
            i = fr.index("pi")
            j = fr.index("pj")
            prev, accs = fr.scatter_pairs(i, j, fr.val["prev"], sums)
            out = [prev]
            for acc in accs:
                out += [builder.extract_element(acc, ir.Constant(_I32, c)) for c in range(2)]
            return context.make_tuple(builder, ret, out + list(args[10 + len(out) :]))

        return sig, codegen

    return intrinsic(typer)


def _pack2(b, x, y):
    v = b.insert_element(ir.Constant(_V2, ir.Undefined), x, ir.Constant(_I32, 0))
    return b.insert_element(v, y, ir.Constant(_I32, 1))


pair_front4 = _pair_front4(True)
pair_front4_tail = _pair_front4(False)
drum_back4 = _drum_back4(True, False)
drum_back4_tail = _drum_back4(False, False)
drum_back4_tangent = _drum_back4(True, True)
drum_back4_tangent_tail = _drum_back4(False, True)
