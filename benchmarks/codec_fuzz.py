"""Random-mutation run of the leg-board codec: no crash, no corrupted frame accepted.

Builds a pool of valid frames of every message type, then feeds the decoder a stream in
which every good frame is followed by a mutated one (bit flips, truncations, insertions,
dropped bytes, splices of two frames), cut into random-sized reads. A decoded frame whose
raw bytes are not one of the frames sent counts as *accepted corrupt*. Prints frames/s,
that count and the reject counters; exits 1 if any corrupted frame was accepted.

    python3 benchmarks/codec_fuzz.py --frames 1000000
"""

from __future__ import annotations

import argparse
import random
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))

from slopelander.legs import codec, messages
from slopelander.legs.messages import N_LEGS, FaultCode, LegState

MUTATIONS = ("bitflip", "truncate", "insert", "drop", "splice")


def random_message(rng: random.Random) -> messages.Message:
    """A valid message of a random type with random in-range fields."""
    kind = rng.randrange(10)
    mask = rng.randrange(1, 16)
    if kind == 0:
        return messages.Hello(rng.randrange(1, 256), rng.randrange(65536))
    if kind == 1:
        return messages.SetFriction(mask, tuple(rng.randrange(1001) for _ in range(N_LEGS)))
    if kind == 2:
        return messages.Loosen(mask)
    if kind == 3:
        return messages.SetAngle(mask, tuple(rng.randrange(3751) for _ in range(N_LEGS)))
    if kind == 4:
        return messages.Stop(mask)
    if kind == 5:
        return messages.Query()
    if kind == 6:
        return messages.HelloReply(1, N_LEGS, rng.randrange(4), 64, rng.getrandbits(32))
    if kind == 7:
        return messages.Ack(rng.randrange(256), rng.randrange(1, 7))
    if kind == 8:
        return messages.Nak(rng.randrange(256), rng.randrange(1, 7), rng.randrange(1, 6))
    legs = []
    for _ in range(N_LEGS):
        state = LegState(rng.randrange(len(LegState)))
        fault = FaultCode(rng.randrange(1, 4)) if state is LegState.FAULT else FaultCode.NONE
        legs.append(
            messages.LegReport(
                state, fault, rng.randrange(-300, 1500), rng.randrange(300), rng.randrange(3751)
            )
        )
    return messages.Status(rng.getrandbits(32), rng.randrange(256), rng.randrange(2), tuple(legs))


def mutate(rng: random.Random, enc: bytes, other: bytes) -> tuple[str, bytes]:
    """One mutation of an encoded frame (delimiter included)."""
    kind = MUTATIONS[rng.randrange(len(MUTATIONS))]
    n = len(enc)
    if kind == "bitflip":
        buf = bytearray(enc)
        for _ in range(rng.randrange(1, 5)):
            pos = rng.randrange(n)
            buf[pos] ^= 1 << rng.randrange(8)
        return kind, bytes(buf)
    if kind == "truncate":
        cut = rng.randrange(1, n - 1)
        return kind, enc[:cut] + (b"\x00" if rng.random() < 0.5 else b"")
    if kind == "insert":
        pos = rng.randrange(n)
        return kind, enc[:pos] + rng.randbytes(rng.randrange(1, 9)) + enc[pos:]
    if kind == "drop":
        buf = bytearray(enc)
        for _ in range(rng.randrange(1, 5)):
            if len(buf) > 1:
                del buf[rng.randrange(len(buf) - 1)]
        return kind, bytes(buf)
    i = rng.randrange(1, n - 1)
    j = rng.randrange(1, len(other) - 1)
    return kind, enc[:i] + other[j:]


def run(frames: int, seed: int, pool_size: int = 4096, batch: int = 2000) -> dict:
    rng = random.Random(seed)
    pool = []
    for _ in range(pool_size):
        msg = random_message(rng)
        pool.append(codec.encode(msg, rng.randrange(256)))
    sent_raw = set()
    decoder = codec.Decoder()
    for enc in pool:  # learn the raw frames by decoding the clean pool once
        (frame,) = decoder.feed(enc)
        sent_raw.add(frame.raw)
    decoder = codec.Decoder()
    accepted_corrupt = 0
    good_accepted = 0
    by_kind = dict.fromkeys(MUTATIONS, 0)
    done = 0
    t0 = time.perf_counter()
    while done < frames:
        count = min(batch, frames - done)
        parts = []
        for _ in range(count):
            parts.append(pool[rng.randrange(pool_size)])
            kind, bad = mutate(rng, pool[rng.randrange(pool_size)], pool[rng.randrange(pool_size)])
            by_kind[kind] += 1
            parts.append(bad)
        stream = b"".join(parts)
        pos = 0
        while pos < len(stream):
            step = rng.randrange(1, 4096)
            for frame in decoder.feed(stream[pos : pos + step]):
                if frame.raw in sent_raw:
                    good_accepted += 1
                else:
                    accepted_corrupt += 1
            pos += step
        done += count
    elapsed = time.perf_counter() - t0
    return {
        "mutated_frames": done,
        "good_frames_interleaved": done,
        "good_or_unchanged_accepted": good_accepted,
        "accepted_corrupt": accepted_corrupt,
        "seconds": elapsed,
        "mutated_frames_per_s": done / elapsed,
        "rejects": decoder.rejects.as_dict(),
        "mutations": by_kind,
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=1_000_000, help="mutated frames to feed")
    parser.add_argument("--seed", type=int, default=1, help="random seed (reproducible run)")
    args = parser.parse_args(argv)
    r = run(args.frames, args.seed)
    rejects = r["rejects"]
    # Frames that reached the CRC with good framing and length: each passes a 32-bit CRC by
    # chance with probability 2^-32; the type, length and field checks behind it catch most.
    crc_checked = rejects["crc"] + rejects["unknown_type"] + rejects["payload_length"]
    crc_checked += rejects["bad_value"] + r["accepted_corrupt"]
    print(f"mutated frames      {r['mutated_frames']}  (+ {r['good_frames_interleaved']} good)")
    print(f"time                {r['seconds']:.1f} s")
    print(f"mutated frames/s    {r['mutated_frames_per_s']:.0f}")
    print(f"accepted corrupt    {r['accepted_corrupt']}")
    print(f"accepted good       {r['good_or_unchanged_accepted']}")
    print("mutations           " + ", ".join(f"{k} {v}" for k, v in r["mutations"].items()))
    print("rejects             " + ", ".join(f"{k} {v}" for k, v in rejects.items()))
    after_crc = rejects["unknown_type"] + rejects["payload_length"] + rejects["bad_value"]
    print(
        f"CRC-checked corrupt {crc_checked}  (expected chance CRC passes"
        f" {crc_checked / 2**32:.1e}; caught after the CRC {after_crc})"
    )
    if r["accepted_corrupt"]:
        print("FAIL: corrupted frames were accepted", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
