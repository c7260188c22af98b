"""coobs bench --only rendered, quick: its four path processes run, and the new path gives today's tracks."""

from experiments.bench.bench_rendered import run


def test_quick_rendered_bench_times_every_path_and_finds_the_same_noise_free_tracks():
    rows = run(quick=True)
    names = [r.benchmark for r in rows]
    for d in (40, 80):
        head = next(r for r in rows if r.benchmark == f"rendered mode, 3 views at {d} m: CPU time, new path")
        # the noise-free images of today's path and of the new path give identical tracks (the bench's check)
        assert "same tracks on all epochs: yes" in head.note, head.note
        assert head.ratio > 0
        for path in ("today", "today, freed buffers kept", "new, default allocator", "new"):
            row = next(r for r in rows if r.benchmark == f"{path} path at {d} m, one thread: CPU ms per camera-frame")
            stages = dict(part.rsplit(" ", 1) for part in row.note.split(", "))
            assert set(stages) == {"render", "SIFT", "match", "label"}
            assert abs(sum(float(v) for v in stages.values()) - row.figure) < 0.25     # the stages add up (each rounded to 0.1)
    assert not any("quickstart" in n for n in names)                                  # not in quick mode
