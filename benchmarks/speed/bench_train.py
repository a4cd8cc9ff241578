"""Stage-1 training throughput at QCAT scale (2,880 sequences of 100–660 samples × 22 channels, hidden 200).

Reference beside it: a bare loop of ``nn.LSTM`` + linear head + masked MSE + Adam over the same batches (same pieces,
same padding, same truncated-BPTT chunks), without what ``fit_predictor`` adds: the elastic net, gradient clipping,
validation every epoch, progress and cancel hooks. Both count real (unpadded) timesteps per second of wall time.
"""

from __future__ import annotations

import time

import numpy as np
import torch
from speed_common import Row, parse_args, qcat_like, record

from training import Normalizer, TrainConfig, cut_pieces, fit_predictor, split_pieces, stage1_batch

HIDDEN = 200


def bare_loop(logs: list[np.ndarray], config: TrainConfig, epochs: int) -> tuple[float, int]:
    """Seconds and real timesteps of ``epochs`` epochs of the bare loop over fit_predictor's training pieces."""
    torch.manual_seed(config.seed)
    rng = np.random.default_rng(config.seed)
    norm = Normalizer.fit(logs)
    data = [norm(a) for a in logs]
    train, val = split_pieces(cut_pieces([len(a) for a in data], config.piece), config.val_fraction, rng)
    length = -(-max(p.length for p in train + val) // config.chunk) * config.chunk
    c = logs[0].shape[1]
    lstm, head = torch.nn.LSTM(c, HIDDEN, batch_first=True), torch.nn.Linear(HIDDEN, c)
    opt = torch.optim.Adam([*lstm.parameters(), *head.parameters()], lr=config.lr)
    t0, steps = time.perf_counter(), 0
    for _ in range(epochs):
        order = rng.permutation(len(train))
        for b in range(0, len(train), config.batch_size):
            group = [train[i] for i in order[b : b + config.batch_size]]
            x, y, mask = (torch.from_numpy(a) for a in stage1_batch(data, group, length))
            state = None
            for c0 in range(0, length, config.chunk):
                m = mask[:, c0 : c0 + config.chunk]
                if not m.any():
                    break
                out, state = lstm(x[:, c0 : c0 + config.chunk], state)  # (B, L, H)
                err = (head(out) - y[:, c0 : c0 + config.chunk]).square().mean(-1)  # (B, L)
                loss = (err * m).sum() / m.sum()
                opt.zero_grad(set_to_none=True)
                loss.backward()
                opt.step()
                state = (state[0].detach(), state[1].detach())
            steps += int(mask.sum())
    return time.perf_counter() - t0, steps


def main() -> None:
    args = parse_args(__doc__)
    n_seq, epochs = (288, 1) if args.quick else (2880, 2)
    logs = qcat_like(n_seq)
    config = TrainConfig(max_epochs=epochs, patience=epochs + 1, seed=0, device=args.device)
    print(f"{n_seq} sequences, {sum(len(x) for x in logs):,} timesteps, {torch.get_num_threads()} threads")

    # warm-up: lazy imports and first-call allocations are paid by neither timed run
    fit_predictor(logs[:16], config=TrainConfig(max_epochs=1, batch_size=8), hidden=HIDDEN)
    bare_loop(logs[:16], TrainConfig(batch_size=8), 1)

    t = time.perf_counter()
    fit = fit_predictor(logs, config=config, hidden=HIDDEN)
    t_ours = time.perf_counter() - t
    ours = fit.timesteps * len(fit.history) / t_ours
    t_bare, steps_bare = bare_loop(logs, config, epochs)
    bare = steps_bare / t_bare
    val = fit.history[-1]["val_loss"]
    row = Row(
        f"stage-1 training throughput, hidden {HIDDEN}, batch {config.batch_size}, {epochs} epoch(s)",
        f"{ours:,.0f} steps/s",
        f"bare nn.LSTM + Adam loop: {bare:,.0f} steps/s",
        f"{ours / bare:.2f}×",
        "≥ 0.9× the bare loop",
        bool(ours / bare >= 0.9),
        f"validation MSE after {len(fit.history)} epoch(s): {val:.4f} (normalised units)",
    )
    record("train", [row], device=args.device)


if __name__ == "__main__":
    main()
