"""Streaming: latency per sample of both stages for one robot, and throughput for 64 robots batched, on one core.

Reference beside each: the naive runtime that calls ``nn.LSTM`` (and the heads) once per sample, as a first port of
the offline model would. The paper's sizes: hidden 200 in both stages, a 5-member ensemble, 22 channels, 6 terrains,
and the workbench's default stage-2 features (``hidden+surprise``: stage 1's hidden state and its per-channel
surprise). Correctness beside the timing: the streamed probabilities against the offline pass over the same log.
The one-member rows run ``StreamingClassifier(..., members=1)``, the deployment of a single fold model.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import torch
from speed_common import Row, fmt_s, parse_args, record, timed
from threadpoolctl import threadpool_limits

from training import (
    Classifier,
    ClassifierConfig,
    ModelBundle,
    Normalizer,
    Predictor,
    PredictorConfig,
    SpectralConfig,
    SpectralSteps,
    StreamingClassifier,
    WindowClassifier,
    WindowClassifierConfig,
    log_frames,
    run_classifiers,
    run_predictor,
)

C, K, HIDDEN, MEMBERS, RATE_HZ = 22, 6, 200, 5, 500.0


def make_bundle(seed: int = 0, members: int = MEMBERS) -> ModelBundle:
    torch.manual_seed(seed)
    predictor = Predictor(PredictorConfig(C, HIDDEN)).eval()
    members = [Classifier(ClassifierConfig(HIDDEN + C, K, HIDDEN)).eval() for _ in range(members)]
    norm = Normalizer(np.zeros(C, np.float32), np.ones(C, np.float32))
    return ModelBundle(
        predictor,
        norm,
        tuple(f"ch{i}" for i in range(C)),
        100.0,
        members,
        tuple("abcdef"),
        feature_mode="hidden+surprise",
    )


class NaiveStream:
    """Per sample: the predictor's ``nn.LSTM`` and head, then each member's ``nn.LSTM`` and head, as offline."""

    def __init__(self, bundle: ModelBundle, streams: int) -> None:
        self.b = bundle
        self.state1 = None
        self.state2 = [None] * len(bundle.classifiers)
        self.streams = streams
        self.prev = None  # stage 1's estimate of this sample, from the step before

    @torch.inference_mode()
    def step(self, x: np.ndarray) -> np.ndarray:
        xt = torch.as_tensor(np.asarray(x, np.float32).reshape(self.streams, 1, -1))  # (B, 1, C)
        z = (xt - torch.from_numpy(self.b.normalizer.mean)) / torch.from_numpy(self.b.normalizer.std)
        estimate, hidden, self.state1 = self.b.predictor(z, self.state1)  # (B, 1, C), (B, 1, H)
        surprise = torch.zeros_like(z) if self.prev is None else (z - self.prev).abs()  # (B, 1, C)
        self.prev = estimate
        feats = torch.cat([hidden, surprise], dim=-1)  # (B, 1, H + C)
        probs = []
        for m, member in enumerate(self.b.classifiers):
            logits, self.state2[m] = member(feats, self.state2[m])  # (B, 1, K)
            probs.append(torch.softmax(logits, -1))
        return torch.stack(probs).mean(0)[:, 0].numpy()  # (B, K)


def step_times(runtime: StreamingClassifier | NaiveStream, samples: np.ndarray) -> np.ndarray:
    """Seconds per ``step`` over ``samples (N, B, C)``, one sample per call, the first 10 untimed."""
    it = iter(samples)
    return timed(lambda: runtime.step(next(it)), repeat=len(samples) - 10, warmup=10)


def main() -> None:
    args = parse_args(__doc__)
    if args.device != "cpu":
        print("streaming runs on the robot's CPU: measured on cpu only")
        return
    torch.set_num_threads(1)  # one core, as on the robot
    bundle = make_bundle()
    rng = np.random.default_rng(0)
    steps = 300 if args.quick else 3000
    log = rng.normal(size=(steps, C)).astype(np.float32)

    # correctness: streamed probabilities against the offline pass over the whole log
    feats = run_predictor(bundle.predictor, bundle.normalizer, [log[:500]])[0].features(bundle.feature_mode)

    def agreement(precision: str, members: int) -> str:
        offline = run_classifiers(bundle.classifiers[:members], [feats])[0].mean(0)  # (T, K)
        streamed = StreamingClassifier(bundle, precision=precision, members=members).run(log[:500])
        agree = float((streamed.argmax(1) == offline.argmax(1)).mean())
        return f"argmax = offline pass on {agree:.2%} of samples, max |Δp| {np.abs(streamed - offline).max():.1e}"

    rows = []
    for streams, precision, members in (
        (1, "float32", MEMBERS),
        (1, "float32", 1),
        (64, "float32", MEMBERS),
        (64, "bfloat16", MEMBERS),
        (64, "bfloat16", 1),
    ):
        fast = StreamingClassifier(bundle, streams=streams, precision=precision, members=members)
        naive = NaiveStream(replace(bundle, classifiers=bundle.classifiers[:members]), streams)
        batch = rng.normal(size=(steps, streams, C)).astype(np.float32)
        with threadpool_limits(1):  # NumPy's BLAS on one core too
            t_fast, t_naive = step_times(fast, batch), step_times(naive, batch)
        med_f, p99_f, med_n = np.median(t_fast), np.percentile(t_fast, 99), np.median(t_naive)
        what = f"{precision}, {members} member{'s' if members > 1 else ''}"
        if streams == 1:
            rows.append(
                Row(
                    f"streaming latency per sample, 1 stream, both stages, {what} (median / p99)",
                    f"{fmt_s(med_f)} / {fmt_s(p99_f)}",
                    f"nn.LSTM per sample: {fmt_s(med_n)} / {fmt_s(np.percentile(t_naive, 99))}",
                    f"{med_n / med_f:.1f}× faster",
                    "≤ 50 µs median, p99 ≤ 200 µs",
                    bool(med_f <= 50e-6 and p99_f <= 200e-6),
                    agreement(precision, members),
                )
            )
        else:
            hz = 1.0 / med_f  # steps per second of all streams at once
            rows.append(
                Row(
                    f"streaming throughput, {streams} robots batched, 1 core, {what}",
                    f"{hz:.0f} Hz per robot ({streams} × {hz:.0f} samples/s)",
                    f"nn.LSTM per sample: {1.0 / med_n:.0f} Hz per robot",
                    f"{med_n / med_f:.1f}× faster",
                    f"≥ {RATE_HZ:.0f} Hz per robot",
                    bool(hz >= RATE_HZ),
                    agreement(precision, members),
                )
            )
    rows += default_family_rows(bundle, rng, steps)
    rows.append(products_alone(bundle, rng))
    rows.append(products_alone(bundle, rng, members=1))
    rows.append(batched_products(bundle, rng))
    record("streaming", rows, device=args.device)


def default_bundle(paper: ModelBundle, seed: int = 0) -> ModelBundle:
    """The default family at the same 22 channels (10 fast at 100 Hz, 12 held: demo-like), 5 members, 6 terrains."""
    torch.manual_seed(seed)
    front = SpectralConfig(frame=40, hop=20, fast=tuple(range(10)), slow=tuple(range(10, C)))
    members = [
        WindowClassifier(WindowClassifierConfig(front.step_width, K, window=front.window)).eval()
        for _ in range(MEMBERS)
    ]
    return replace(paper, classifiers=members, feature_mode="spectral", spectral=front)


def memory_bandwidth() -> float:
    """Bytes per second this core copies (a 128 MB float32 array read and written, best of 5): the memory-traffic
    bound of the rows that read weights."""
    src = np.ones(32 * 2**20, np.float32)
    dst = np.empty_like(src)
    with threadpool_limits(1):
        best = min(timed(lambda: np.copyto(dst, src), repeat=5, warmup=1))
    return 2 * src.nbytes / best


def default_family_rows(paper: ModelBundle, rng: np.random.Generator, steps: int) -> list[Row]:
    """The default family's step (front end every sample, the window network when a frame completes), against the
    paper family's fused step at the same channels, measured in the same run."""
    bundle = default_bundle(paper)
    log = rng.normal(size=(max(steps, 1000), C)).astype(np.float32)
    offline = run_classifiers(
        bundle.classifiers, [SpectralSteps(log_frames(log, bundle.spectral), len(log), bundle.spectral)]
    )[0].mean(0)
    streamed = StreamingClassifier(bundle).run(log)
    check = (
        f"argmax = offline pass on {float((streamed.argmax(1) == offline.argmax(1)).mean()):.2%} of samples, "
        f"max |Δp| {np.abs(streamed - offline).max():.1e}"
    )
    bandwidth = memory_bandwidth()

    def bound(clf: StreamingClassifier) -> str:
        step = clf._step
        nbytes = sum(a.nbytes for a in (step.mix, step.mix_b, step.taps, step.conv_b, step.head, step.head_b))
        floor = fmt_s(nbytes / bandwidth)
        return f"{nbytes / 1e6:.2f} MB of weights per frame: ≥ {floor} at {bandwidth / 1e9:.0f} GB/s"

    rows = []
    # a frame completes every `hop` samples and costs most of the work: the median is a step without one, so the
    # p99 (a frame's step) and the mean (the sustained cost) go beside it, and throughput is by the mean
    for members in (1, MEMBERS):
        batch = rng.normal(size=(max(steps, 2000), 1, C)).astype(np.float32)  # p99 of 5 % frame steps: 100 frames
        clf = StreamingClassifier(bundle, members=members)
        with threadpool_limits(1):
            t_new = step_times(clf, batch)
            t_ref = step_times(StreamingClassifier(paper, members=members), batch)
        med, p99, ref = np.median(t_new), np.percentile(t_new, 99), np.median(t_ref)
        rows.append(
            Row(
                f"default family: streaming latency per sample, 1 stream, {members} member"
                f"{'s' if members > 1 else ''} (median / p99 / mean)",
                f"{fmt_s(med)} / {fmt_s(p99)} / {fmt_s(np.mean(t_new))}",
                f"paper family, fused: {fmt_s(ref)} / {fmt_s(np.percentile(t_ref, 99))} / {fmt_s(np.mean(t_ref))}",
                f"p99 {np.percentile(t_ref, 99) / p99:.1f}× faster",
                f"≤ 30 µs median, p99 ≤ 100 µs; {bound(clf)}",
                bool(med <= 30e-6 and p99 <= 100e-6),
                check,
            )
        )
    streams = 64
    batch = rng.normal(size=(steps, streams, C)).astype(np.float32)
    clf = StreamingClassifier(bundle, streams=streams)
    with threadpool_limits(1):
        t_new = step_times(clf, batch)
        t_ref = step_times(StreamingClassifier(paper, streams=streams), batch)
    mean, ref_mean = np.mean(t_new), np.mean(t_ref)
    rows.append(
        Row(
            f"default family: streaming throughput, {streams} robots batched, 1 core, {MEMBERS} members (mean step)",
            f"{1 / mean:.0f} Hz per robot",
            f"paper family, fused: {1 / ref_mean:.0f} Hz per robot",
            f"{ref_mean / mean:.1f}× faster",
            f"≥ {RATE_HZ:.0f} Hz per robot; {bound(clf)}",
            bool(1 / mean >= RATE_HZ),
            check,
        )
    )
    return rows


def _products_and_step(bundle: ModelBundle, rng: np.random.Generator, *, members: int, streams: int, repeat: int):
    """Median seconds of a float32 step's LSTM matrix products alone and of the whole step, and the weights read."""
    step = StreamingClassifier(bundle, streams=streams, members=members)._step
    x = rng.normal(size=(streams, C)).astype(np.float32)
    if members == 1:
        weights = (step.w1, step.w2_one)

        def products() -> None:
            np.matmul(step.u1, step.w1, out=step.g1)
            np.matmul(step.u2in, step.w2_one, out=step.g2[0])
    else:
        weights = (step.w1, step.w2, step.u2)
        feats = np.zeros((streams, step.n_feats), np.float32)  # the step builds its features anew each time

        def products() -> None:
            np.matmul(step.u1, step.w1, out=step.g1)
            np.matmul(feats, step.w2, out=step.g2in)
            np.matmul(step.hh2, step.u2, out=step.g2)

    with threadpool_limits(1):
        t_prod = np.median(timed(products, repeat=repeat, warmup=10))
        t_step = np.median(timed(lambda: step(x), repeat=repeat, warmup=10))
    return t_prod, t_step, weights


def products_alone(bundle: ModelBundle, rng: np.random.Generator, *, members: int = MEMBERS) -> Row:
    """The profile of a 1-stream float32 step: its matrix products alone, against the whole step."""
    t_prod, t_step, weights = _products_and_step(bundle, rng, members=members, streams=1, repeat=3000)
    nbytes = sum(a.nbytes for a in weights)
    return Row(
        f"profile: a 1-stream float32 step's LSTM matrix products alone, {members} member"
        f"{'s' if members > 1 else ''} (median)",
        fmt_s(t_prod),
        f"the whole step: {fmt_s(t_step)}",
        f"{t_prod / t_step:.0%} of the step",
        f"{nbytes / 1e6:.1f} MB of weights read per step: {nbytes / t_prod / 1e9:.0f} GB/s",
        None,
    )


def batched_products(bundle: ModelBundle, rng: np.random.Generator, streams: int = 64) -> Row:
    """The profile of the 64-robot float32 step: its matrix products alone, and the arithmetic rate they reach."""
    t_prod, t_step, weights = _products_and_step(bundle, rng, members=MEMBERS, streams=streams, repeat=300)
    flops = 2 * streams * sum(a.size for a in weights)  # multiply-adds of the products
    return Row(
        f"profile: a {streams}-stream float32 step's LSTM matrix products alone, {MEMBERS} members (median)",
        fmt_s(t_prod),
        f"the whole step: {fmt_s(t_step)}",
        f"{t_prod / t_step:.0%} of the step",
        f"{flops / 1e6:.0f} MFLOP per step at {flops / t_prod / 1e9:.0f} GFLOP/s; {RATE_HZ:.0f} Hz needs "
        f"{flops * RATE_HZ / 1e9:.0f} GFLOP/s",
        None,
    )


if __name__ == "__main__":
    main()
