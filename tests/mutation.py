"""Byte-level mutations of files, for reader fuzzing (tests/flow/test_robustness.py with NumPy's random
numbers, tests/io/test_fuzz_readers.py with hypothesis): truncation, byte flips, deleted, inserted and
duplicated chunks, dropped lines, extreme integers written over binary fields."""

from __future__ import annotations

from typing import Callable

import numpy as np

#: inserted at random places: numbers at the edges of what parsers take, keywords of every format
TOKENS = [b"nan", b"inf", b"-inf", b"1e999", b"-0", b"99999999999999999999", b"-5", b"0x10", b"", b" ", b"\n",
          b"f", b"v", b"//", b"/", b"\\\n", b"element vertex 99999999999\n", b"end_header\n",
          b"property list uchar int",
          b"\x00", b"\xff\xfe", b"3 0 1 2\n", b"4 0 0 0 0\n",
          b"solid x\n", b"facet normal 0 0 1\n", b"vertex 1e38 0 0\n", b"endfacet\n", b"endsolid\n",
          b"def Mesh \"Z\" {\n", b"}", b"{", b"]", b"[(", b")", b"@./other.usda@", b"@/dev/zero@",
          b"references = @./x.usda@</M>\n", b"subLayers = [@../up.usda@]\n", b"points.timeSamples = { 1: [] }\n",
          b"int[] faceVertexCounts = [-1, 2147483647]\n", b"uniform token orientation = \"leftHanded\"\n",
          b"\xef\xbb\xbf", b"-2147483648", b"4294967295"]

#: written over 4 or 8 bytes of a binary file (counts, offsets, sizes)
EXTREMES = [0, 1, 0x7F, 0xFF, 0x7FFFFFFF, 0x80000000, 0xFFFFFFFF, 2**62, 2**63 - 1, 2**64 - 1]

Draw = Callable[[int, int], int]    # draw(lo, hi): an integer in [lo, hi)


def mutate(data: bytes, draw: Draw, n_ops: int = 6) -> bytes:
    """``data`` with one to three mutations; ``n_ops=7`` adds extreme integers written over binary fields."""
    b = bytearray(data)
    for _ in range(draw(1, 4)):
        op = draw(0, n_ops)
        if not b:
            b = bytearray(TOKENS[draw(0, len(TOKENS))])
            continue
        i = draw(0, len(b))
        if op == 0:
            b = b[:i]                                             # truncate
        elif op == 1:
            b[i] = draw(0, 256)                                   # flip a byte
        elif op == 2:
            del b[i:draw(i, min(len(b), i + 200) + 1)]            # delete a chunk
        elif op == 3:
            b[i:i] = TOKENS[draw(0, len(TOKENS))]                 # insert a nasty token
        elif op == 4:
            j = draw(0, len(b))
            b[i:i] = b[j:draw(j, min(len(b), j + 300) + 1)]      # duplicate a chunk
        elif op == 5:
            nl = np.flatnonzero(np.frombuffer(bytes(b), np.uint8) == 10)[:2000]
            if nl.size > 2:                                       # drop whole lines
                a_ = draw(0, nl.size)
                z_ = draw(0, nl.size - 1)
                a_, z_ = sorted((int(nl[a_]), int(nl[z_ + (z_ >= a_)])))
                b = b[:a_] + b[z_:]
        else:
            width = (4, 8)[draw(0, 2)]                            # an extreme integer over a binary field
            value = EXTREMES[draw(0, len(EXTREMES))] % (1 << (8 * width))
            b[i:i + width] = value.to_bytes(width, ("little", "big")[draw(0, 2)])
    return bytes(b)


def numpy_draw(rng: np.random.Generator) -> Draw:
    return lambda lo, hi: int(rng.integers(lo, hi))
