"""Compiled (numba) kernels of the motion policy graph: edge generators and searches.

The gracefully prepares graph's edges are generated from the lattice
(:class:`gracenav.planning.graph.LatticeEdges`) by :func:`predecessors_of` and
:func:`_successors_of`; the single-goal tree searches of :mod:`gracenav.planning` run
either on a stored reversed graph or on those generators. They live in one file because
numba's on-disk cache notices a change of a kernel's own file only, not of the kernels
it calls in another file.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numba import njit

#: Most distinct edge costs searched with one FIFO queue each (see
#: :mod:`gracenav.planning`).
_MAX_QUEUES = 256
_TABLE = 1024  # open-addressing table from an edge cost to its queue (a power of 2)
# Status of the compiled searches.
_DONE, _NEGATIVE, _TOO_MANY_COSTS, _REVISITED = 0, 1, 2, 3


# The compiled edge generators below take the arrays of LatticeEdges.kernel_args. A
# row is found from (type, point) in the dense table, or by bisection among its type's
# rows (point ascending) when there is none.


@njit(cache=True, nogil=True, inline="always")
def lattice_row(
    t: Any, point: Any, row_point: Any, type_first: Any, lookup: Any, n_points: Any
) -> Any:
    """Library row of type ``t`` at lattice point ``point``, −1 if none."""
    if lookup.size:
        return lookup[point * (type_first.size - 1) + t]
    lo = type_first[t]
    hi = type_first[t + 1]
    while lo < hi:
        mid = (lo + hi) >> 1
        if row_point[mid] < point:
            lo = mid + 1
        else:
            hi = mid
    if lo < type_first[t + 1] and row_point[lo] == point:
        return lo
    return -1


@njit(cache=True, nogil=True, inline="always")
def predecessors_of(
    j: Any,
    out_i: Any,
    out_w: Any,
    type_cost: Any,
    row_type: Any,
    row_point: Any,
    nx: Any,
    ny: Any,
    pred_ptr: Any,
    pred_type: Any,
    succ_ptr: Any,
    succ_type: Any,
    off_x: Any,
    off_y: Any,
    type_first: Any,
    lookup: Any,
) -> int:
    """Write the policies that gracefully prepare ``j`` (ascending) and their costs
    (``type_cost`` of their type) to ``out_i``, ``out_w``; return how many.

    Candidates are probed one end-offset group (one table row) at a time, then the
    few found are sorted by row."""
    n_points = nx * ny
    tj = row_type[j]
    pj = row_point[j]
    jy = pj // nx
    jx = pj - jy * nx
    m = 0
    for a in range(pred_ptr[tj], pred_ptr[tj + 1]):
        t1 = pred_type[a]
        ix = jx - off_x[t1]
        iy = jy - off_y[t1]
        if ix < 0 or ix >= nx or iy < 0 or iy >= ny:
            continue
        i = lattice_row(t1, iy * nx + ix, row_point, type_first, lookup, n_points)
        if i < 0 or i == j:
            continue
        w = type_cost[t1]
        k = m  # insertion sort: rows ascending
        while k > 0 and out_i[k - 1] > i:
            out_i[k] = out_i[k - 1]
            out_w[k] = out_w[k - 1]
            k -= 1
        out_i[k] = i
        out_w[k] = w
        m += 1
    return m


@njit(cache=True, nogil=True, inline="always")
def _successors_of(
    i: Any,
    out: Any,
    row_type: Any,
    row_point: Any,
    nx: Any,
    ny: Any,
    pred_ptr: Any,
    pred_type: Any,
    succ_ptr: Any,
    succ_type: Any,
    off_x: Any,
    off_y: Any,
    type_first: Any,
    lookup: Any,
) -> int:
    """Write the policies that ``i`` gracefully prepares (ascending) to ``out``."""
    n_points = nx * ny
    ti = row_type[i]
    pi = row_point[i]
    ey = pi // nx + off_y[ti]
    ex = pi % nx + off_x[ti]
    if ex < 0 or ex >= nx or ey < 0 or ey >= ny:
        return 0
    m = 0
    for a in range(succ_ptr[ti], succ_ptr[ti + 1]):
        j = lattice_row(succ_type[a], ey * nx + ex, row_point, type_first, lookup, n_points)
        if j >= 0 and j != i:
            out[m] = j
            m += 1
    return m


@njit(cache=True, nogil=True)
def _count_edges(counts: Any, forward: Any, *args: Any) -> None:
    """Out-degree (``forward``) or in-degree of every row, from the forward generator
    (whose probes of the lookup table are contiguous)."""
    (
        row_type,
        row_point,
        nx,
        ny,
        pred_ptr,
        pred_type,
        succ_ptr,
        succ_type,
        off_x,
        off_y,
        type_first,
        lookup,
    ) = args
    buf = np.empty(max(succ_type.size, 1), np.int64)
    if not forward:
        counts[:] = 0
    for r in range(counts.size):
        k = _successors_of(
            r,
            buf,
            row_type,
            row_point,
            nx,
            ny,
            pred_ptr,
            pred_type,
            succ_ptr,
            succ_type,
            off_x,
            off_y,
            type_first,
            lookup,
        )
        if forward:
            counts[r] = k
        else:
            for a in range(k):
                counts[buf[a]] += 1


@njit(cache=True, nogil=True)
def _count_rows_edges(rows: Any, *args: Any) -> int:
    """Total out-degree of the library ``rows`` (from the forward generator)."""
    (
        row_type,
        row_point,
        nx,
        ny,
        pred_ptr,
        pred_type,
        succ_ptr,
        succ_type,
        off_x,
        off_y,
        type_first,
        lookup,
    ) = args
    buf = np.empty(max(succ_type.size, 1), np.int64)
    total = 0
    for r in rows:
        total += _successors_of(
            r,
            buf,
            row_type,
            row_point,
            nx,
            ny,
            pred_ptr,
            pred_type,
            succ_ptr,
            succ_type,
            off_x,
            off_y,
            type_first,
            lookup,
        )
    return total


@njit(cache=True, nogil=True)
def _count_all_edges(
    row_type: Any,
    row_point: Any,
    nx: Any,
    ny: Any,
    pred_ptr: Any,
    pred_type: Any,
    succ_ptr: Any,
    succ_type: Any,
    off_x: Any,
    off_y: Any,
    type_first: Any,
    lookup: Any,
) -> int:
    """E, the edges of the whole graph: what :func:`_successors_of` finds, summed over
    the rows. With the dense lookup table each row's candidates are probed; without it,
    the rows of a type and of each of its successor types are merged by point (both
    point-ascending, and so are the end points of the first), in O(rows of the two)
    instead of a bisection per candidate."""
    if lookup.size:
        buf = np.empty(max(succ_type.size, 1), np.int64)
        total = 0
        for r in range(row_type.size):
            total += _successors_of(
                r,
                buf,
                row_type,
                row_point,
                nx,
                ny,
                pred_ptr,
                pred_type,
                succ_ptr,
                succ_type,
                off_x,
                off_y,
                type_first,
                lookup,
            )
        return total
    total = 0
    for t in range(type_first.size - 1):
        a0 = type_first[t]
        a1 = type_first[t + 1]
        ox = off_x[t]
        oy = off_y[t]
        for k in range(succ_ptr[t], succ_ptr[t + 1]):
            u = succ_type[k]
            if u == t and ox == 0 and oy == 0:
                continue  # a row's only match would be itself
            b = type_first[u]
            b1 = type_first[u + 1]
            for r in range(a0, a1):
                if b >= b1:
                    break
                p = row_point[r]
                py = p // nx
                ex = p - py * nx + ox
                ey = py + oy
                if ex < 0 or ex >= nx or ey < 0 or ey >= ny:
                    continue
                e = ey * nx + ex
                while b < b1 and row_point[b] < e:
                    b += 1
                if b < b1 and row_point[b] == e:
                    total += 1
    return total


@njit(cache=True, nogil=True)
def _fill_edges(indptr: Any, indices: Any, forward: Any, *args: Any) -> None:
    """Column indices of every row's edges (``forward``), or row indices of every
    column's, ascending, from the forward generator. (One loop per direction, each
    with the lattice arrays as its own parameters: a loop that tested ``forward``
    inside and read them from the tuple ran 4 times slower.)"""
    if forward:
        _fill_forward(indptr, indices, *args)
    else:
        _fill_reverse(indptr, indices, *args)


@njit(cache=True, nogil=True)
def _fill_forward(
    indptr: Any,
    indices: Any,
    row_type: Any,
    row_point: Any,
    nx: Any,
    ny: Any,
    pred_ptr: Any,
    pred_type: Any,
    succ_ptr: Any,
    succ_type: Any,
    off_x: Any,
    off_y: Any,
    type_first: Any,
    lookup: Any,
) -> None:
    """The successors of every row, written into its stretch of ``indices``."""
    for r in range(indptr.size - 1):
        _successors_of(
            r,
            indices[indptr[r] : indptr[r + 1]],
            row_type,
            row_point,
            nx,
            ny,
            pred_ptr,
            pred_type,
            succ_ptr,
            succ_type,
            off_x,
            off_y,
            type_first,
            lookup,
        )


@njit(cache=True, nogil=True)
def _fill_reverse(
    indptr: Any,
    indices: Any,
    row_type: Any,
    row_point: Any,
    nx: Any,
    ny: Any,
    pred_ptr: Any,
    pred_type: Any,
    succ_ptr: Any,
    succ_type: Any,
    off_x: Any,
    off_y: Any,
    type_first: Any,
    lookup: Any,
) -> None:
    """Every row appended to the columns of its successors (rows ascending)."""
    buf = np.empty(max(succ_type.size, 1), np.int64)
    pos = indptr[:-1].copy()
    for r in range(indptr.size - 1):
        k = _successors_of(
            r,
            buf,
            row_type,
            row_point,
            nx,
            ny,
            pred_ptr,
            pred_type,
            succ_ptr,
            succ_type,
            off_x,
            off_y,
            type_first,
            lookup,
        )
        for a in range(k):
            j = buf[a]
            indices[pos[j]] = r
            pos[j] += 1


# The compiled searches below fill ``dist`` (cost-to-go, inf if unreachable) and ``nxt``
# (next policy, -1 at the goal and where unreachable) from the reversed graph in CSR
# form (``indptr``, ``indices``, ``weights``: row j lists the policies i that prepare j
# and the cost of executing i), and return a status. A policy is *settled* when its
# cost-to-go is final; settled keys never decrease. Each relaxation of i from j that
# ties with the current best replaces ``nxt[i]`` if j has the same cost-to-go as the
# current choice and a smaller index (see the module notes): with positive costs every
# successor that attains ``dist[i]`` settles before ``i``, so all are compared.


@njit(cache=True, nogil=True)
def _search_queues(indptr: Any, indices: Any, weights: Any, goal: int, dist: Any, nxt: Any) -> int:
    """Dijkstra with one FIFO queue per distinct edge cost (see the module notes).

    Queue entries live in one pool of N + 1 slots, linked per queue; a policy is queued
    again only if reached at a lower cost, which graphs whose edges cost their source
    policy never do. Returns ``_TOO_MANY_COSTS`` or ``_REVISITED`` when the pool or
    the queues run out, and the caller searches again with :func:`_search_heap`.
    """
    return _queues(indptr, indices, weights, goal, dist, nxt, False, weights, *_no_lattice())


@njit(cache=True, nogil=True)
def _search_queues_lattice(type_cost: Any, goal: int, dist: Any, nxt: Any, *lattice: Any) -> int:
    """:func:`_search_queues` on edges generated from the lattice (``lattice``:
    :meth:`gracenav.planning.graph.LatticeEdges.kernel_args`, ``type_cost`` the cost of
    each type)."""
    buf_i, buf_w = _buffers(lattice[4])
    return _queues(buf_i[:1], buf_i, buf_w, goal, dist, nxt, True, type_cost, *lattice)


@njit(cache=True, nogil=True)
def _queues(
    indptr: Any,
    indices: Any,
    weights: Any,
    goal: int,
    dist: Any,
    nxt: Any,
    implicit: bool,
    type_cost: Any,
    *lattice: Any,
) -> int:
    """The queue search of :func:`_search_queues`; with ``implicit``, the edges into j
    are generated from the lattice into ``indices`` and ``weights`` (scratch buffers
    then) instead of read from the reversed graph."""
    (
        row_type,
        row_point,
        nx,
        ny,
        pred_ptr,
        pred_type,
        succ_ptr,
        succ_type,
        off_x,
        off_y,
        type_first,
        lookup,
    ) = lattice
    n = dist.size
    for k in range(n):
        dist[k] = np.inf
        nxt[k] = -1
    settled = np.zeros(n, np.bool_)
    cap = n + 1
    e_node = np.empty(cap, np.int32)  # pool: policy, key and next entry of its queue
    e_key = np.empty(cap, np.float64)
    e_next = np.empty(cap, np.int32)
    q_head = np.full(_MAX_QUEUES, -1, np.int32)
    q_tail = np.full(_MAX_QUEUES, -1, np.int32)
    q_cost = np.empty(_MAX_QUEUES, np.float64)
    table = np.full(_TABLE, -1, np.int32)
    h_queue = np.empty(_MAX_QUEUES, np.int32)  # binary heap of the non-empty queues,
    h_key = np.empty(_MAX_QUEUES, np.float64)  # keyed by their head entry
    # The goal, alone in the queue of cost 0 (hash slot 0).
    q_cost[0] = 0.0
    n_queues = 1
    table[0] = 0
    dist[goal] = 0.0
    e_node[0] = goal
    e_key[0] = 0.0
    e_next[0] = -1
    count = 1
    q_head[0] = 0
    q_tail[0] = 0
    h_queue[0] = 0
    h_key[0] = 0.0
    h_size = 1
    last_cost = -1.0  # the queue of the last cost looked up
    last_queue = 0
    while h_size > 0:
        c = h_queue[0]
        e = q_head[c]
        j = e_node[e]
        dj = e_key[e]
        nh = e_next[e]
        q_head[c] = nh
        # Queue c moves down the heap with its new head, or leaves it.
        v = c
        kv = np.inf
        if nh == -1:
            q_tail[c] = -1
            h_size -= 1
            if h_size > 0:
                v = h_queue[h_size]
                kv = h_key[h_size]
        else:
            kv = e_key[nh]
        if h_size > 0:
            p = 0
            while True:
                ch = 2 * p + 1
                if ch >= h_size:
                    break
                if ch + 1 < h_size and h_key[ch + 1] < h_key[ch]:
                    ch += 1
                if h_key[ch] < kv:
                    h_queue[p] = h_queue[ch]
                    h_key[p] = h_key[ch]
                    p = ch
                else:
                    break
            h_queue[p] = v
            h_key[p] = kv
        if settled[j] or dj > dist[j]:
            continue  # an entry left behind by a lower cost
        settled[j] = True
        if implicit:
            lo = 0
            hi = predecessors_of(
                j,
                indices,
                weights,
                type_cost,
                row_type,
                row_point,
                nx,
                ny,
                pred_ptr,
                pred_type,
                succ_ptr,
                succ_type,
                off_x,
                off_y,
                type_first,
                lookup,
            )
        else:
            lo = indptr[j]
            hi = indptr[j + 1]
        for k in range(lo, hi):
            i = indices[k]
            w = weights[k]
            if not w >= 0.0:
                return _NEGATIVE
            d = dj + w
            di = dist[i]
            if d < di:
                dist[i] = d
                nxt[i] = j
                if w == last_cost:
                    t = last_queue
                else:
                    h = (int(w * 1048576.0) * 40503) & (_TABLE - 1) if w < 1e9 else 1
                    while True:
                        t = table[h]
                        if t == -1:
                            if n_queues == _MAX_QUEUES:
                                return _TOO_MANY_COSTS
                            t = n_queues
                            n_queues += 1
                            q_cost[t] = w
                            table[h] = t
                            break
                        if q_cost[t] == w:
                            break
                        h = (h + 1) & (_TABLE - 1)
                    last_cost = w
                    last_queue = t
                if count == cap:
                    return _REVISITED
                e = count
                count += 1
                e_node[e] = i
                e_key[e] = d
                e_next[e] = -1
                if q_tail[t] == -1:
                    q_head[t] = e
                    p = h_size  # queue t enters the heap
                    h_size += 1
                    while p > 0:
                        pp = (p - 1) >> 1
                        if h_key[pp] > d:
                            h_queue[p] = h_queue[pp]
                            h_key[p] = h_key[pp]
                            p = pp
                        else:
                            break
                    h_queue[p] = t
                    h_key[p] = d
                else:
                    e_next[q_tail[t]] = e
                q_tail[t] = e
            elif d == di and (w > 0.0 or not settled[i]):
                m = nxt[i]
                if j < m and dj == dist[m]:
                    nxt[i] = j
    return _DONE


@njit(cache=True, nogil=True)
def _search_heap(indptr: Any, indices: Any, weights: Any, goal: int, dist: Any, nxt: Any) -> int:
    """Dijkstra with an indexed binary heap (decrease-key), for any non-negative costs."""
    return _heap(indptr, indices, weights, goal, dist, nxt, False, weights, *_no_lattice())


@njit(cache=True, nogil=True)
def _search_heap_lattice(type_cost: Any, goal: int, dist: Any, nxt: Any, *lattice: Any) -> int:
    """:func:`_search_heap` on edges generated from the lattice."""
    buf_i, buf_w = _buffers(lattice[4])
    return _heap(buf_i[:1], buf_i, buf_w, goal, dist, nxt, True, type_cost, *lattice)


@njit(cache=True, nogil=True)
def _heap(
    indptr: Any,
    indices: Any,
    weights: Any,
    goal: int,
    dist: Any,
    nxt: Any,
    implicit: bool,
    type_cost: Any,
    *lattice: Any,
) -> int:
    """The heap search of :func:`_search_heap` (``implicit`` as in :func:`_queues`)."""
    (
        row_type,
        row_point,
        nx,
        ny,
        pred_ptr,
        pred_type,
        succ_ptr,
        succ_type,
        off_x,
        off_y,
        type_first,
        lookup,
    ) = lattice
    n = dist.size
    for k in range(n):
        dist[k] = np.inf
        nxt[k] = -1
    heap = np.empty(n, np.int32)
    key = np.empty(n, np.float64)
    pos = np.full(n, -1, np.int32)  # heap slot; -1 never queued, -2 settled
    dist[goal] = 0.0
    heap[0] = goal
    key[0] = 0.0
    pos[goal] = 0
    size = 1
    while size > 0:
        j = heap[0]
        dj = key[0]
        pos[j] = -2
        size -= 1
        if size > 0:
            v = heap[size]
            kv = key[size]
            p = 0
            while True:
                c = 2 * p + 1
                if c >= size:
                    break
                if c + 1 < size and key[c + 1] < key[c]:
                    c += 1
                if key[c] < kv:
                    heap[p] = heap[c]
                    key[p] = key[c]
                    pos[heap[p]] = p
                    p = c
                else:
                    break
            heap[p] = v
            key[p] = kv
            pos[v] = p
        if implicit:
            lo = 0
            hi = predecessors_of(
                j,
                indices,
                weights,
                type_cost,
                row_type,
                row_point,
                nx,
                ny,
                pred_ptr,
                pred_type,
                succ_ptr,
                succ_type,
                off_x,
                off_y,
                type_first,
                lookup,
            )
        else:
            lo = indptr[j]
            hi = indptr[j + 1]
        for k in range(lo, hi):
            i = indices[k]
            w = weights[k]
            if not w >= 0.0:
                return _NEGATIVE
            d = dj + w
            di = dist[i]
            if d < di:
                dist[i] = d
                nxt[i] = j
                p = pos[i]
                if p == -1:
                    p = size
                    size += 1
                while p > 0:
                    q = (p - 1) >> 1
                    if key[q] > d:
                        heap[p] = heap[q]
                        key[p] = key[q]
                        pos[heap[p]] = p
                        p = q
                    else:
                        break
                heap[p] = i
                key[p] = d
                pos[i] = p
            elif d == di and (w > 0.0 or pos[i] != -2):
                m = nxt[i]
                if j < m and dj == dist[m]:
                    nxt[i] = j
    return _DONE


@njit(cache=True, nogil=True)
def _no_lattice() -> Any:
    """Empty stand-ins for the lattice arrays of a search on a stored reversed graph."""
    i32 = np.zeros(0, np.int32)
    i64 = np.zeros(1, np.int64)
    return (i32, i32, 1, 1, i64, i32, i64, i32, i64, i64, i64, i32)


@njit(cache=True, nogil=True)
def _buffers(pred_ptr: Any) -> Any:
    """Scratch arrays for the edges into one policy: as many as the most predecessor
    types of a type."""
    m = 1
    for t in range(pred_ptr.size - 1):
        m = max(m, pred_ptr[t + 1] - pred_ptr[t])
    return np.empty(m, np.int64), np.empty(m, np.float64)


@njit(cache=True, nogil=True, inline="always")
def _gauge(dx: Any, dy: Any, h_x: Any, h_y: Any) -> float:
    """max(0, max_f h_x[f] dx + h_y[f] dy): the A* heuristic of a displacement."""
    h = 0.0
    for f in range(h_x.size):
        v = h_x[f] * dx + h_y[f] * dy
        if v > h:
            h = v
    return h


# The A* searches below keep their open set in a binary heap of entries (f, -g, row) in
# three arrays ``hf``, ``hg``, ``hn`` with lazy deletion (an entry whose g is no longer
# the row's is skipped when popped).
@njit(cache=True, nogil=True, inline="always")
def _before(f1: Any, g1: Any, n1: Any, f2: Any, g2: Any, n2: Any) -> bool:
    """Heap order of two entries (f, -g, row): lower f, then deeper, then lower row."""
    return f1 < f2 or (f1 == f2 and (g1 < g2 or (g1 == g2 and n1 < n2)))


@njit(cache=True, nogil=True, inline="always")
def _sift_down(hf: Any, hg: Any, hn: Any, p: Any, size: Any) -> None:
    vf = hf[p]
    vg = hg[p]
    vn = hn[p]
    while True:
        c = 2 * p + 1
        if c >= size:
            break
        if c + 1 < size and _before(hf[c + 1], hg[c + 1], hn[c + 1], hf[c], hg[c], hn[c]):
            c += 1
        if _before(hf[c], hg[c], hn[c], vf, vg, vn):
            hf[p] = hf[c]
            hg[p] = hg[c]
            hn[p] = hn[c]
            p = c
        else:
            break
    hf[p] = vf
    hg[p] = vg
    hn[p] = vn


@njit(cache=True, nogil=True, inline="always")
def _pop(hf: Any, hg: Any, hn: Any, size: Any) -> Any:
    """Remove the first entry of the heap of ``size`` entries; returns the new size."""
    size -= 1
    if size > 0:
        hf[0] = hf[size]
        hg[0] = hg[size]
        hn[0] = hn[size]
        _sift_down(hf, hg, hn, 0, size)
    return size


@njit(cache=True, nogil=True, inline="always")
def _push(hf: Any, hg: Any, hn: Any, size: Any, f: Any, g: Any, n: Any) -> Any:
    """Add the entry (f, g, n) to the heap of ``size`` entries, in arrays of twice the
    length when they are full; returns (hf, hg, hn, size + 1)."""
    cap = hf.size
    if size == cap:
        cap *= 2
        hf2 = np.empty(cap, np.float64)
        hg2 = np.empty(cap, np.float64)
        hn2 = np.empty(cap, np.int64)
        hf2[:size] = hf[:size]
        hg2[:size] = hg[:size]
        hn2[:size] = hn[:size]
        hf, hg, hn = hf2, hg2, hn2
    p = size
    while p > 0:
        q = (p - 1) >> 1
        if _before(f, g, n, hf[q], hg[q], hn[q]):
            hf[p] = hf[q]
            hg[p] = hg[q]
            hn[p] = hn[q]
            p = q
        else:
            break
    hf[p] = f
    hg[p] = g
    hn[p] = n
    return hf, hg, hn, size + 1


@njit(cache=True, nogil=True)
def _astar(
    starts: Any,
    goal: int,
    join_rows: Any,
    join_cost: Any,
    type_cost: Any,
    h_x: Any,
    h_y: Any,
    h_point: Any,
    g_cost: Any,
    parent: Any,
    row_type: Any,
    row_point: Any,
    nx: Any,
    ny: Any,
    pred_ptr: Any,
    pred_type: Any,
    succ_ptr: Any,
    succ_type: Any,
    off_x: Any,
    off_y: Any,
    type_first: Any,
    lookup: Any,
) -> Any:
    """A* from ``starts`` to ``goal`` on the edges generated forward from the lattice.

    The heuristic of policy i is max(0, max_f h_x[f] Δx + h_y[f] Δy) for the lattice
    displacement (Δx, Δy) (cells) from its start point to the goal's: the gauge of the
    polygon of (end offset / cost) of the policies, a lower bound of the cost-to-go that
    is consistent (see :func:`gracenav.planning.plan_path`), or ``h_point`` of its start
    point where that is larger (:func:`_points_cost_to_go`, also consistent). Fills
    ``g_cost`` (cost from the nearest start, inf where not reached) and ``parent``
    (−1 at the starts); returns (status, policies expanded, row where the search
    joined a known path, −1 if none).

    ``join_rows`` (ascending) are policies of known optimal cost-to-go ``join_cost``
    (the goal with 0, or the policies of an earlier optimal path): a search that
    settles one does not expand it but queues the path through it at cost g + its
    cost-to-go, and stops when such an entry is the cheapest in the queue. A binary heap of
    (f, −g, row) with lazy deletion: ties go to the deeper, then the smaller row.
    """
    n = g_cost.size
    for k in range(n):
        g_cost[k] = np.inf
        parent[k] = -1
    closed = np.zeros(n, np.bool_)
    gy = row_point[goal] // nx
    gx = row_point[goal] - gy * nx
    hf = np.empty(1024, np.float64)
    hg = np.empty(1024, np.float64)
    hn = np.empty(1024, np.int64)
    size = 0
    buf = np.empty(max(succ_type.size, 1), np.int64)
    for s in starts:
        if g_cost[s] == 0.0:
            continue
        g_cost[s] = 0.0
        py = row_point[s] // nx
        px = row_point[s] - py * nx
        f = max(_gauge(gx - px, gy - py, h_x, h_y), h_point[row_point[s]])
        hf, hg, hn, size = _push(hf, hg, hn, size, f, 0.0, s)
    expanded = 0
    while size > 0:
        i = hn[0]
        gi = -hg[0]
        size = _pop(hf, hg, hn, size)
        if i < 0:  # a queued join: no open policy can do better
            return _DONE, expanded, join_rows[-i - 1]
        if closed[i] or gi > g_cost[i]:
            continue
        closed[i] = True
        expanded += 1
        k = np.searchsorted(join_rows, i)
        if k < join_rows.size and join_rows[k] == i:
            if join_cost[k] == 0.0:
                return _DONE, expanded, i
            d = gi + join_cost[k]
            hf, hg, hn, size = _push(hf, hg, hn, size, d, -d, -k - 1)
            continue
        w = type_cost[row_type[i]]
        if not w >= 0.0:
            return _NEGATIVE, expanded, -1
        m = _successors_of(
            i,
            buf,
            row_type,
            row_point,
            nx,
            ny,
            pred_ptr,
            pred_type,
            succ_ptr,
            succ_type,
            off_x,
            off_y,
            type_first,
            lookup,
        )
        for a in range(m):
            j = buf[a]
            d = gi + w
            if d < g_cost[j]:
                g_cost[j] = d
                parent[j] = i
                py = row_point[j] // nx
                px = row_point[j] - py * nx
                f = d + max(_gauge(gx - px, gy - py, h_x, h_y), h_point[row_point[j]])
                hf, hg, hn, size = _push(hf, hg, hn, size, f, -d, j)
    return _DONE, expanded, -1


# The heuristic of plan_path on maps whose ways detour: a search over lattice points
# (not policies) in which a point moves by the end offset of any policy type that has a
# policy there, at that offset's cheapest cost (see PreparesGraph.point_moves).
@njit(cache=True, nogil=True)
def _point_move_mask(row_type: Any, row_point: Any, type_move: Any, points: int, words: int) -> Any:
    """Bit k of ``mask[p, k // 64]`` is set iff some library row at point p is of a type
    whose move (``type_move``, −1 for none) is k."""
    mask = np.zeros((points, words), np.uint64)
    for r in range(row_type.size):
        k = type_move[row_type[r]]
        if k >= 0:
            mask[row_point[r], k >> 6] |= np.uint64(1) << np.uint64(k & 63)
    return mask


@njit(cache=True, nogil=True)
def _points_cost_to_go(
    sources: Any,
    targets: Any,
    forward: bool,
    nx: int,
    ny: int,
    mask: Any,
    move_dx: Any,
    move_dy: Any,
    move_cost: Any,
    dist: Any,
) -> int:
    """Dijkstra over the lattice points' moves from the ``sources`` (cost 0); fills
    ``dist`` (one entry per lattice point) and returns how many target points it did
    not settle (none can be reached).

    Backward (``forward`` False; the source the goal's point): ``dist[p]`` bounds from
    below the cost-to-go of every policy that starts at p. Forward (the sources the
    queries' points): it bounds the cost from a query policy to every policy at p. A
    point p moves to p + move k iff bit k of ``mask[p]`` is set, at ``move_cost[k]``
    (>= 0). The search stops once every target point is settled, at cost R, or when it
    runs out of points, R then its largest cost: the points it settled keep their exact
    cost, the others get R (theirs is at least R, or inf: not inf itself, which would
    leave a search keyed by it to close such policies in no order of cost). Both are
    consistent bounds: through any library edge
    i -> j, from point p to q by i's move, dist[p] <= move_cost + dist[q] (backward) and
    dist[q] <= dist[p] + move_cost (forward), move_cost <= cost(i)."""
    points = nx * ny
    for p in range(points):
        dist[p] = np.inf
    settled = np.zeros(points, np.bool_)
    pending = np.zeros(points, np.bool_)
    waiting = 0
    for p in targets:
        if not pending[p]:
            pending[p] = True
            waiting += 1
    hf = np.empty(1024, np.float64)
    hg = np.empty(1024, np.float64)
    hn = np.empty(1024, np.int64)
    size = 0
    for p in sources:
        if dist[p] != 0.0:
            dist[p] = 0.0
            hf, hg, hn, size = _push(hf, hg, hn, size, 0.0, 0.0, p)
    radius = 0.0
    while size > 0:
        a = hn[0]
        da = hf[0]
        size = _pop(hf, hg, hn, size)
        if settled[a] or da > dist[a]:
            continue
        settled[a] = True
        radius = da
        if pending[a]:
            waiting -= 1
            if waiting == 0:
                break
        ay = a // nx
        ax = a - ay * nx
        for k in range(move_dx.size):
            if forward:
                bx = ax + move_dx[k]
                by = ay + move_dy[k]
                mover = a
            else:
                bx = ax - move_dx[k]
                by = ay - move_dy[k]
                mover = by * nx + bx
            if bx < 0 or bx >= nx or by < 0 or by >= ny:
                continue
            b = by * nx + bx
            if settled[b] or not (mask[mover, k >> 6] >> np.uint64(k & 63)) & np.uint64(1):
                continue
            d = da + move_cost[k]
            if d < dist[b]:
                dist[b] = d
                hf, hg, hn, size = _push(hf, hg, hn, size, d, 0.0, b)
    for p in range(points):
        if not settled[p]:
            dist[p] = radius
    return waiting


# The resumable goal-directed tree (gracenav.planning.LazyPolicyTree): a backward A*
# from the goal over the predecessors, whose state (tentative and final costs, next
# policies, closed flags and the open heap) lives in arrays the caller keeps between
# calls; the open heap is that of _astar (_push, _pop).
_BUDGET = 4  # status: the expansion budget of the call ran out


@njit(cache=True, nogil=True, inline="always")
def _query_gauge(
    row: Any, cx: Any, cy: Any, r: Any, row_point: Any, nx: Any, h_x: Any, h_y: Any
) -> float:
    """max(0, gauge(p - c) - r) for the start point p of ``row``: a lower bound of the
    cost from any query point q with gauge(q - c) <= r (the gauge is sublinear), as
    consistent as the gauge itself, and 0 at every query point."""
    py = row_point[row] // nx
    px = row_point[row] - py * nx
    h = _gauge(px - cx, py - cy, h_x, h_y) - r
    return h if h > 0.0 else 0.0


@njit(cache=True, nogil=True, inline="always")
def _query_bound(
    row: Any,
    cx: Any,
    cy: Any,
    r: Any,
    row_point: Any,
    nx: Any,
    h_x: Any,
    h_y: Any,
    h_point: Any,
) -> float:
    """The heuristic of a lazy tree's row: :func:`_query_gauge`, or the queries' point
    bound of its start point (``h_point``, empty for none) where that is larger."""
    h = _query_gauge(row, cx, cy, r, row_point, nx, h_x, h_y)
    if h_point.size:
        hp = h_point[row_point[row]]
        if hp > h:
            return hp
    return h


@njit(cache=True, nogil=True)
def _lazy_settle(
    goal: int,
    queries: Any,
    best: bool,
    budget: int,
    cx: float,
    cy: float,
    radius: float,
    type_cost: Any,
    h_x: Any,
    h_y: Any,
    h_point: Any,
    g: Any,
    dist: Any,
    nxt: Any,
    parent: Any,
    closed: Any,
    mark: Any,
    hf: Any,
    hg: Any,
    hn: Any,
    size: int,
    implicit: bool,
    indptr: Any,
    indices: Any,
    weights: Any,
    row_type: Any,
    row_point: Any,
    nx: Any,
    ny: Any,
    pred_ptr: Any,
    pred_type: Any,
    succ_ptr: Any,
    succ_type: Any,
    off_x: Any,
    off_y: Any,
    type_first: Any,
    lookup: Any,
) -> Any:
    """Resume the backward A* of a lazy tree until the ``queries`` are closed.

    ``g`` holds tentative costs-to-go (inf where not reached), ``dist`` and ``nxt`` the
    final cost-to-go and next policy of closed rows, ``hf``, ``hg``, ``hn`` the open
    heap (``size`` entries). The heap is first re-keyed with the heuristic of the new
    queries (the gauge from the nearest query point, (qx, qy) in cells, or the
    queries' point bound ``h_point`` where larger: consistent lower bounds of the cost
    from a query to a row) and cleaned of stale entries; then
    rows are closed in order of g + h until every query row is closed (``best``: until
    the cheapest query row and every query row of equal cost are closed), the heap is
    empty (every row that reaches the goal is closed) or ``budget`` (>= 0) rows have
    been closed. No query rows: until the heap is empty. ``mark`` (all False) is
    scratch. Returns (status, size, hf, hg, hn, rows closed).

    ``parent`` holds each reached row's best successor so far: among the closed
    successors j that relaxed it with cost + dist[j] == g exactly, the smallest dist[j],
    then the smallest row (the rule of the whole tree); it becomes the row's next
    policy when the row closes. With positive costs every such successor closes first
    (g + h of a successor is below the row's by at least 1e-9 times its cost, the
    margin of the gauge), so the choice is among all of them.
    """
    remaining = 0
    best_cost = np.inf
    for q in queries:
        if closed[q]:
            if dist[q] < best_cost:
                best_cost = dist[q]
        elif not mark[q]:
            mark[q] = True
            remaining += 1
    if queries.size > 0 and remaining == 0:
        return _DONE, size, hf, hg, hn, 0
    if not best:
        best_cost = np.inf
    # Re-key: one entry per open row (its current tentative cost), f with the new h.
    m = 0
    for k in range(size):
        v = hn[k]
        gv = -hg[k]
        if closed[v] or gv > g[v]:
            continue
        hf[m] = gv + _query_bound(v, cx, cy, radius, row_point, nx, h_x, h_y, h_point)
        hg[m] = -gv
        hn[m] = v
        m += 1
    size = m
    for p in range(size // 2 - 1, -1, -1):
        _sift_down(hf, hg, hn, p, size)
    if implicit:
        buf_i, buf_w = _buffers(pred_ptr)
    else:
        buf_i, buf_w = np.empty(1, np.int64), np.empty(1, np.float64)
    expanded = 0
    status = _DONE
    while size > 0:
        if hf[0] > best_cost:
            break
        if budget >= 0 and expanded >= budget:
            status = _BUDGET
            break
        i = hn[0]
        gi = -hg[0]
        size = _pop(hf, hg, hn, size)
        if closed[i] or gi > g[i]:
            continue
        closed[i] = True
        dist[i] = gi
        expanded += 1
        ci = type_cost[row_type[i]]
        if not ci >= 0.0:
            status = _NEGATIVE
            break
        nxt[i] = parent[i]
        if mark[i]:
            mark[i] = False
            remaining -= 1
            if best and gi < best_cost:
                best_cost = gi
        if implicit:
            lo = 0
            hi = predecessors_of(
                i,
                buf_i,
                buf_w,
                type_cost,
                row_type,
                row_point,
                nx,
                ny,
                pred_ptr,
                pred_type,
                succ_ptr,
                succ_type,
                off_x,
                off_y,
                type_first,
                lookup,
            )
        else:
            lo = indptr[i]
            hi = indptr[i + 1]
        for k in range(lo, hi):
            if implicit:
                u = buf_i[k]
                w = buf_w[k]
            else:
                u = indices[k]
                w = weights[k]
            if closed[u]:
                continue
            if not w >= 0.0:
                status = _NEGATIVE
                break
            d = gi + w
            if d == g[u]:  # an equally good successor: the smaller cost-to-go, then row
                pu = parent[u]
                if gi < dist[pu] or (gi == dist[pu] and i < pu):
                    parent[u] = i
                continue
            if d < g[u]:
                g[u] = d
                parent[u] = i
                f = d + _query_bound(u, cx, cy, radius, row_point, nx, h_x, h_y, h_point)
                hf, hg, hn, size = _push(hf, hg, hn, size, f, -d, u)
        if status == _NEGATIVE or (queries.size > 0 and remaining == 0):
            break  # (a row is closed only with its predecessors relaxed)
    for q in queries:
        mark[q] = False
    return status, size, hf, hg, hn, expanded
