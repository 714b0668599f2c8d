#!/usr/bin/env python3
"""The main thread's and all threads' samples in 20 ms steps from a `perf script -F tid,time,ip,sym` dump of a
`perf record -g` run of `synthtrack-cli bench preprocess` (gpu/bench/devrun_h28c.sh). Steps where few of the
machine's threads ran, and what the main thread ran then, are the serial work to look at (issue 16).

Usage: perf_timeline.py DUMP [STEP_S], or perf_timeline.py --inclusive DUMP [TOP]: each of our functions' (st::,
cv::, fftw) samples with it anywhere on the stack, on the main thread and on all threads, in ms of CPU
at perf's 2999 Hz (complete only for a build with -DST_FRAME_POINTERS=ON, recorded with --call-graph fp).
The timeline starts where the simulation's last sample is; the main
thread is the lowest thread id. Each line: time from there, samples of every thread (n) and of the main thread
(m), the main thread's two commonest user functions (kernel frames skipped) and everyone's three.
"""
import collections
import re
import sys

KERNEL_PREFIXES = ('__', 'asm_', 'exc_', 'do_', 'handle_', 'clear_page', 'entry', 'x64', 'syscall', 'irq',
                   'sysvec', '_raw', 'native', 'folio', 'alloc_', 'get_page', 'vma', 'lock_', 'up_', 'down_',
                   'rwsem', 'madvise', 'populate', 'futex', 'schedule', 'finish_task', 'tlb', 'flush', 'mmap',
                   'unmap', 'zap', 'release_pages', 'free_', 'page', 'memcg', 'lru', 'mem_cgroup', 'rmqueue',
                   'post_alloc', 'prep_', 'kernel_', 'cond_resched', 'try_', 'ksys', 'vm_', 'filemap', 'set_pte',
                   'pte_', 'pmd_', 'count_memcg', 'mod_', 'charge', 'update', 'smp_', 'rcu', 'tick', 'shmem')


def load(path):
    samples, cur = [], None
    for line in open(path):
        if not line.strip():
            if cur:
                samples.append(cur)
            cur = None
        elif not line.startswith(('\t', ' ' * 8)):
            p = line.split()
            cur = (int(p[0]), float(p[1].rstrip(':')), [])
        elif cur is not None:
            p = line.strip().split(None, 1)
            cur[2].append(p[1] if len(p) > 1 else '?')
    if cur:
        samples.append(cur)
    return samples


def short(sym):
    sym = sym.replace('(anonymous namespace)', 'anon')
    sym = re.sub(r'\(.*', '', sym)
    for _ in range(2):
        sym = re.sub(r'<[^<>]*>', '', sym)
    return sym[:70]


def user(stack):
    for s in stack:
        if s != '[unknown]' and not s.startswith(KERNEL_PREFIXES):
            return short(s)
    for s in stack:
        if s != '[unknown]':
            return 'K:' + short(s)
    return '?'


def inclusive(path, top):
    samples = load(path)
    start = max(t for _, t, st in samples if st and 'st::sim::' in ' '.join(st[:3]))
    main_tid = min(tid for tid, _, _ in samples)
    mine, every = collections.Counter(), collections.Counter()
    for tid, t, st in samples:
        if t < start:
            continue
        names = {short(s) for s in st}
        names = {n for n in names if n.startswith(('st::', 'cv::', 'fftw'))}
        every.update(names)
        if tid == main_tid:
            mine.update(names)
    for title, counts in (('main thread', mine), ('all threads', every)):
        print(f'--- {title}, inclusive CPU ms')
        for name, n in counts.most_common(top):
            print(f'{n / 2.999:8.1f}  {name}')


def main():
    if sys.argv[1] == '--inclusive':
        inclusive(sys.argv[2], int(sys.argv[3]) if len(sys.argv) > 3 else 40)
        return
    samples = load(sys.argv[1])
    step = float(sys.argv[2]) if len(sys.argv) > 2 else 0.02
    start = max(t for _, t, st in samples if st and 'st::sim::' in ' '.join(st[:3]))
    main_tid = min(tid for tid, _, _ in samples)
    buckets = collections.defaultdict(list)
    for tid, t, st in samples:
        if t >= start:
            buckets[int((t - start) / step)].append((tid, st))
    for b in sorted(buckets):
        every = buckets[b]
        mine = [st for tid, st in every if tid == main_tid]
        m = collections.Counter(user(st) for st in mine).most_common(2)
        a = collections.Counter(user(st) for _, st in every).most_common(3)
        print(f"{b * step:5.2f} n={len(every):4d} m={len(mine):3d} | M: "
              f"{'; '.join(f'{k}:{v}' for k, v in m)} | A: {'; '.join(f'{k}:{v}' for k, v in a)}")


if __name__ == '__main__':
    main()
