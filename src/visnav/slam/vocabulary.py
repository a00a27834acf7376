"""A binary bag-of-words vocabulary for place recognition (DBoW2-style scoring).

Words are cluster centres of ORB descriptors found by k-majority (k-means for
binary vectors: assign by Hamming distance, recentre by per-bit majority),
seeded for determinism. A keyframe's bag-of-words vector is the tf-idf weighted
word histogram, L1-normalised; two vectors score ``1 - |a - b|_1 / 2`` in [0, 1].

The vocabulary can be trained on the fly from the first keyframes of a run, or
trained once on other data, saved (:meth:`Vocabulary.save`, an ``.npz``) and
loaded for later runs.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

from visnav.slam.errors import SlamInputError
from visnav.slam.features import DescArray

__all__ = ["BowDatabase", "Vocabulary"]

F32 = NDArray[np.float32]


def _nearest(descriptors: DescArray, words: DescArray) -> NDArray[np.int64]:
    matcher = cv2.BFMatcher(cv2.NORM_HAMMING)
    matches = matcher.match(np.ascontiguousarray(descriptors), np.ascontiguousarray(words))
    out = np.empty(len(descriptors), dtype=np.int64)
    for m in matches:
        out[m.queryIdx] = m.trainIdx
    return out


class Vocabulary:
    """Binary visual words with idf weights.

    Args:
        words: (K, 32) uint8 word descriptors.
        idf: (K,) inverse document frequencies.
    """

    def __init__(self, words: DescArray, idf: F32) -> None:
        if words.ndim != 2 or words.shape[1] != 32 or words.dtype != np.uint8 or len(words) < 2:
            text = f"vocabulary words must be (K >= 2, 32) uint8, got {words.shape} {words.dtype}"
            raise SlamInputError(text)
        if idf.shape != (len(words),):
            text = f"vocabulary idf has shape {idf.shape}, expected ({len(words)},)"
            raise SlamInputError(text)
        self.words = np.ascontiguousarray(words)
        self.idf = idf.astype(np.float32)

    @property
    def size(self) -> int:
        """Number of words."""
        return len(self.words)

    @classmethod
    def train(
        cls,
        documents: list[DescArray],
        *,
        k: int = 500,
        iterations: int = 8,
        seed: int = 0,
        max_descriptors: int = 40000,
    ) -> Vocabulary:
        """Cluster descriptors of several images into ``k`` words (k-majority).

        Args:
            documents: per image, its (N_i, 32) descriptors.
            k: number of words (fewer if there are fewer distinct descriptors).
            iterations: assignment / majority rounds.
            seed: seeds the initial centres and the subsampling.
            max_descriptors: subsample the training set to at most this many.
        """
        rng = np.random.default_rng(seed)
        data = np.concatenate([d for d in documents if len(d)], axis=0) if documents else None
        if data is None or len(data) < 2:
            text = "cannot train a vocabulary: fewer than 2 descriptors"
            raise SlamInputError(text)
        if len(data) > max_descriptors:
            data = data[np.sort(rng.choice(len(data), max_descriptors, replace=False))]
        uniq = np.unique(data, axis=0)
        k = int(min(k, len(uniq)))
        centres = uniq[np.sort(rng.choice(len(uniq), k, replace=False))].copy()
        bits = np.unpackbits(data, axis=1)
        for _ in range(iterations):
            assign = _nearest(data, centres)
            counts = np.bincount(assign, minlength=k)
            flat = (assign[:, None] * 256 + np.arange(256)[None, :]).reshape(-1)
            sums = np.bincount(flat, weights=bits.reshape(-1), minlength=k * 256).reshape(k, 256)
            filled = counts > 0
            majority = (2 * sums[filled] > counts[filled, None]).astype(np.uint8)
            new = centres.copy()
            new[filled] = np.packbits(majority, axis=1)
            if np.array_equal(new, centres):
                break
            centres = new
        # idf over the training documents
        n_docs = max(len(documents), 1)
        df = np.zeros(k, dtype=np.float64)
        for d in documents:
            if len(d):
                df[np.unique(_nearest(d, centres))] += 1
        idf = np.log(n_docs / np.maximum(df, 1.0)).astype(np.float32)
        # words never seen in a document still carry some weight
        idf[df == 0] = float(np.log(n_docs + 1.0))
        return cls(centres, idf)

    def transform(self, descriptors: DescArray) -> F32:
        """Return the L1-normalised tf-idf vector (K,) of one image's descriptors."""
        v = np.zeros(self.size, dtype=np.float32)
        if len(descriptors) == 0:
            return v
        words = _nearest(descriptors, self.words)
        tf = np.bincount(words, minlength=self.size).astype(np.float32) / len(descriptors)
        v = (tf * self.idf).astype(np.float32)
        s = float(v.sum())
        return v / s if s > 0 else v

    @staticmethod
    def score(a: F32, b: F32) -> float:
        """L1 similarity of two normalised vectors, in [0, 1]."""
        return float(1.0 - 0.5 * np.abs(a - b).sum())

    def save(self, path: str | Path) -> Path:
        """Write the vocabulary as ``.npz`` (words and idf)."""
        p = Path(path)
        np.savez_compressed(p, words=self.words, idf=self.idf)
        return p if p.suffix == ".npz" else p.with_suffix(p.suffix + ".npz")

    @classmethod
    def load(cls, path: str | Path) -> Vocabulary:
        """Read a vocabulary written by :meth:`save`."""
        p = Path(path)
        if not p.is_file():
            text = f"vocabulary file {p} does not exist (write one with Vocabulary.save)"
            raise SlamInputError(text)
        with np.load(p) as z:
            return cls(z["words"].astype(np.uint8), z["idf"].astype(np.float32))


class BowDatabase:
    """Bag-of-words vectors of keyframes, scored all at once."""

    def __init__(self, vocabulary: Vocabulary) -> None:
        self.vocabulary = vocabulary
        self._vectors = np.zeros((64, vocabulary.size), dtype=np.float32)
        self._ids: list[int] = []

    def __len__(self) -> int:
        return len(self._ids)

    def add(self, kf_id: int, vector: F32) -> None:
        """Store a keyframe's vector."""
        n = len(self._ids)
        if n == len(self._vectors):
            grown = np.zeros((2 * n, self.vocabulary.size), dtype=np.float32)
            grown[:n] = self._vectors
            self._vectors = grown
        self._vectors[n] = vector
        self._ids.append(kf_id)

    def query(self, vector: F32) -> tuple[NDArray[np.int64], F32]:
        """Return ``(keyframe_ids, scores)`` of every stored keyframe."""
        n = len(self._ids)
        if n == 0:
            return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.float32)
        scores = 1.0 - 0.5 * np.abs(self._vectors[:n] - vector[None, :]).sum(axis=1)
        return np.asarray(self._ids, dtype=np.int64), scores.astype(np.float32)
