"""Link fault injection: what a noisy serial cable does to a byte stream.

Faults apply per direction, to whole frames (each chunk the relay moves is
a run of complete frames ending in 0x00 plus possibly a partial tail):

- bit errors: each bit flips with probability ``ber``;
- dropped bytes: each byte is lost with probability ``drop_rate``;
- bursts: with probability ``burst_rate`` per frame, ``burst_len`` bytes are
  overwritten with random values;
- duplicated frames and reordered frames (a frame held back and sent after
  the next), each with its probability per frame;
- stalls: with probability ``stall_rate`` per chunk the direction stops
  delivering for ``stall_s`` seconds of wall time (bytes queue up).

Everything is drawn from one seeded generator, so a faulty run replays.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np


@dataclass(frozen=True)
class FaultConfig:
    ber: float = 0.0
    drop_rate: float = 0.0
    burst_rate: float = 0.0
    burst_len: int = 8
    duplicate_rate: float = 0.0
    reorder_rate: float = 0.0
    stall_rate: float = 0.0
    stall_s: float = 0.05

    def __post_init__(self):
        for name in ("ber", "drop_rate", "burst_rate", "duplicate_rate", "reorder_rate", "stall_rate"):
            v = getattr(self, name)
            if not (0.0 <= v <= 1.0):
                raise ValueError(f"{name}: a probability in [0, 1], got {v}")
        if self.burst_len < 1:
            raise ValueError(f"burst_len: at least 1, got {self.burst_len}")
        if self.stall_s < 0:
            raise ValueError(f"stall_s: non-negative, got {self.stall_s}")

    @property
    def clean(self) -> bool:
        return not any(
            (self.ber, self.drop_rate, self.burst_rate, self.duplicate_rate, self.reorder_rate, self.stall_rate)
        )

    def as_dict(self):
        return asdict(self)


@dataclass
class FaultCounts:
    bits_flipped: int = 0
    bytes_dropped: int = 0
    bursts: int = 0
    frames_duplicated: int = 0
    frames_reordered: int = 0
    stalls: int = 0
    frames_touched: int = 0  # frames whose bytes were altered (flip, drop or burst)
    frames_intact: int = 0  # frames passed on as they were sent (the far side can answer these)


class FaultInjector:
    """Applies a FaultConfig to chunks of one direction of the link."""

    def __init__(self, cfg: FaultConfig, rng: np.random.Generator):
        self.cfg = cfg
        self.rng = rng
        self.counts = FaultCounts()
        self._tail = b""  # partial frame waiting for its 0x00
        self._held = None  # frame held back for reordering
        self.originals = set()  # every frame offered, as sent (to prove what is delivered was sent)

    def _corrupt(self, frame: bytes) -> bytes:
        cfg, rng = self.cfg, self.rng
        buf = np.frombuffer(frame, dtype=np.uint8).copy()
        touched = False
        if cfg.ber > 0 and buf.size:
            flips = rng.random(buf.size * 8) < cfg.ber
            if flips.any():
                bits = np.packbits(flips.astype(np.uint8))
                buf ^= bits[: buf.size]
                self.counts.bits_flipped += int(flips.sum())
                touched = True
        if cfg.burst_rate > 0 and buf.size and rng.random() < cfg.burst_rate:
            start = int(rng.integers(0, buf.size))
            end = min(buf.size, start + cfg.burst_len)
            buf[start:end] = rng.integers(0, 256, end - start, dtype=np.uint8)
            self.counts.bursts += 1
            touched = True
        if cfg.drop_rate > 0 and buf.size:
            keep = rng.random(buf.size) >= cfg.drop_rate
            if not keep.all():
                self.counts.bytes_dropped += int((~keep).sum())
                buf = buf[keep]
                touched = True
        self.counts.frames_touched += int(touched)
        self.counts.frames_intact += int(not touched)
        return buf.tobytes()

    def apply(self, chunk: bytes) -> bytes:
        """Faulty version of ``chunk``; a trailing partial frame is kept
        until its 0x00 arrives, so frame-level faults see whole frames."""
        if self.cfg.clean:
            return chunk
        data = self._tail + chunk
        cut = data.rfind(b"\x00")
        if cut < 0:
            self._tail = data
            return b""
        self._tail = data[cut + 1 :]
        out = []
        for frame in data[: cut + 1].split(b"\x00")[:-1]:
            frame = frame + b"\x00"
            self.originals.add(frame)
            if self.cfg.reorder_rate > 0 and self._held is None and self.rng.random() < self.cfg.reorder_rate:
                self._held = frame
                self.counts.frames_reordered += 1
                continue
            out.append(self._corrupt(frame))
            if self.cfg.duplicate_rate > 0 and self.rng.random() < self.cfg.duplicate_rate:
                out.append(self._corrupt(frame))
                self.counts.frames_duplicated += 1
            if self._held is not None:
                out.append(self._corrupt(self._held))
                self._held = None
        return b"".join(out)

    def stall_now(self) -> float:
        """Seconds this direction stalls before delivering the next chunk."""
        if self.cfg.stall_rate > 0 and self.rng.random() < self.cfg.stall_rate:
            self.counts.stalls += 1
            return self.cfg.stall_s
        return 0.0
