"""Explicit vector operations of the passes that know no contact law (numba intrinsics).

The gather of the pair rows (:func:`gather4`, :func:`gather4_spins`), the compaction's
four-pair touch test (:func:`touch_bits4`), and the per-disk passes of a step over the
flat ``2N`` rows (:func:`kick8`, :func:`tangent8`, :func:`speed2_lanes`); the passes of
:mod:`granpipe.engine.passes` call them for every law.

LLVM does not vectorise the gathers of :mod:`granpipe.engine.passes` (the pair indices
are data, and numba leaves LLVM's SLP vectoriser off by default since it miscompiled
code: numba PR #8852, issues #8705 and #8681), so a scalar gather costs eight loads,
four subtractions and four stores per pair. :func:`gather4` takes four listed pairs at
once: per pair and field (positions, velocities) one two-wide load from each disk's
``(x, y)`` in the flat ``2N`` row and one subtraction, the lanes combined in registers
and stored as row vectors, reading the flat rows directly rather than copied per-disk
records (the alternatives and their timings: docs/engine_performance.md, "Round 5").
Lane by lane the arithmetic is the IEEE arithmetic of the scalar code, so results are
bit-identical.

Numba's own on-disk cache keys a kernel on its own source file only; the package's
locator (:mod:`granpipe._jit`) keys every kernel on all jitted sources, this module
included, so an edit here recompiles the kernels that use it in the next process.
"""

from __future__ import annotations

from llvmlite import ir
from numba.core import cgutils, types
from numba.extending import intrinsic

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
    "touch_bits4",
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

    The four running sums of :func:`granpipe.engine.passes.final_kick`, the same IEEE
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
# a half-step velocity is bad unless |w| < BIG (the bound of every per-disk pass)
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
    the per-disk pass of a step (:func:`granpipe.engine.passes.kick_drift`) over the
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
    tangent vector's per-disk pass (:func:`granpipe.engine.passes.tangent_kicks`) over
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
    ``spins`` is ``()`` or, for laws with spin, the rows ``(tw, tt, inv_i, radius)``: the
    spin's perturbation is kicked the same way (by ``h (tt inv_i)``) and ``(r_i w)² mob_i``
    of its half-kicked value ``w`` (``r_i`` the radius) is added to ``q_i``.
    """

    def typer(typingctx, tr, tv, tf, im, mob, prev, contacts, h, dt, n, spins):
        if not _f64_vectors(tr, tv, tf, im, mob, prev, *spins) or len(spins) not in (0, 4):
            return None
        ret = types.UniTuple(types.float64, 12)
        sig = ret(tr, tv, tf, im, mob, prev, contacts, h, dt, n, spins)

        def codegen(context, builder, signature, args):
            ra, va, fa, ia, ma, qa, ca = _arrays(context, builder, sig, args, 7)
            spin = [
                context.make_array(t)(context, builder, builder.extract_value(args[10], c))
                for c, t in enumerate(sig.args[10])
            ]
            h8, dt8 = (_bcast(builder, args[c], 8) for c in (7, 8))
            h4 = _bcast(builder, args[7], 4)
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
                if spin:
                    wp, tp, jp, ap = (_vec_at(builder, x.data, i, 4) for x in spin)
                    tt, ji = builder.load(tp, align=8), builder.load(jp, align=8)
                    sa = builder.fmul(h4, builder.fmul(tt, ji))
                    su = builder.fadd(builder.load(wp, align=8), sa)
                    builder.store(builder.fadd(su, sa) if mode == 1 else su, wp, align=8)
                    if mode != 0:
                        rw = builder.fmul(builder.load(ap, align=8), su)
                        q = builder.fadd(q, builder.fmul(builder.fmul(rw, rw), mx))
                if mode != 0:
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


def _call(b, name, args):
    """Call the LLVM intrinsic ``name`` on vectors of one type (the result's too)."""
    vt = args[0].type
    fnty = ir.FunctionType(vt, [vt] * len(args))
    fn = b.module.globals.get(name) or ir.Function(b.module, fnty, name=name)
    return b.call(fn, args)


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
        return v

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
        return [b.shuffle_vector(lo, hi, ir.Constant(m4, [c, c + 2, c + 4, c + 6])) for c in (0, 1)]

    def store_lanes(self, name, v, off=None):
        """``name[off + k .. off + k+3] = v`` (a vector of four lanes)."""
        b = self.b
        at = self._at(off)
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


@intrinsic
def touch_bits4(typingctx, pos, pi, pj, k, ssum):
    """``sum over lanes c of 2**c`` for the listed pairs ``k .. k+3`` that are not apart,
    i.e. ``not (dx² + dy² > ssum²)`` with ``(dx, dy)`` from the flat ``2N`` positions
    ``pos`` (the test, and its treatment of NaN, of the scalar compaction in
    :func:`granpipe.engine.passes.gather_compact`; the same IEEE operations). Zero when
    all four are apart: the compacted gather skips such groups without a branch per pair.
    """
    sig = types.int64(pos, pi, pj, k, ssum)

    def codegen(context, builder, signature, args):
        fr = _Frame(context, builder, signature, args, ("pos", "pi", "pj", "k", "ssum"), True)
        dx, dy = fr.xy_diff("pos", fr.index("pi"), fr.index("pj"))
        s = fr.lanes("ssum")
        r2 = builder.fadd(builder.fmul(dx, dx), builder.fmul(dy, dy))
        apart = builder.fcmp_ordered(">", r2, builder.fmul(s, s))
        bits = builder.bitcast(apart, ir.IntType(4))
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
                fr.store_lanes("rows", lanes, at)
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
