"""Place recognition over keyframes: a bag of binary words learnt from the map itself (no ROS).

Vocabulary: ORB descriptors clustered by k-majority (k-means for binary descriptors: Hamming
assignment, per-bit majority centres; Grana et al. 2013), the flat version of DBoW2's
vocabulary tree (Gálvez-López & Tardós 2012). It is learnt from the map's own keyframes — no
vocabulary trained on other data ships with the package — first when the map has
``vocabulary_first`` keyframes, again each time it has doubled (up to 512 keyframes), on at most
20 descriptors per word; before that, every keyframe is a candidate. The vocabulary is saved
with the map, so localisation reuses it.

Scoring: tf-idf weighted word histograms, L1-normalised, DBoW2's L1 score
s = 1 − ½‖v₁ − v₂‖₁ ∈ [0, 1].
"""
from __future__ import annotations

import threading

import cv2
import numpy as np

from raspv_slam.config import SlamConfig

RETRAIN_UNTIL = 512              # keyframes; afterwards the vocabulary stays
SAMPLES_PER_WORD = 20
ITERATIONS = 8


class Vocabulary:
    """``words`` (K, 32) uint8 binary centres."""

    def __init__(self, words: np.ndarray) -> None:
        words = np.ascontiguousarray(words, dtype=np.uint8)
        if words.ndim != 2 or words.shape[1] != 32 or not len(words):
            raise ValueError(f"a vocabulary is (K, 32) uint8 ORB words, got {words.shape}")
        self.words = words
        self._bf = cv2.BFMatcher(cv2.NORM_HAMMING)

    def __len__(self) -> int:
        return len(self.words)

    @classmethod
    def train(cls, descriptors: np.ndarray, k: int, seed: int = 0) -> "Vocabulary":
        """k-majority clustering of binary descriptors (N, 32) into at most ``k`` words."""
        rng = np.random.default_rng(seed)
        d = np.unique(np.ascontiguousarray(descriptors, dtype=np.uint8), axis=0)
        if len(d) > k * SAMPLES_PER_WORD:
            d = d[rng.choice(len(d), k * SAMPLES_PER_WORD, replace=False)]
        k = min(k, len(d))
        words = d[rng.choice(len(d), k, replace=False)].copy()
        bits = np.unpackbits(d, axis=1).astype(np.uint16)            # (N, 256)
        bf = cv2.BFMatcher(cv2.NORM_HAMMING)
        for _ in range(ITERATIONS):
            labels = np.array([m.trainIdx for m in bf.match(d, words)])
            order = np.argsort(labels, kind="stable")
            counts = np.bincount(labels, minlength=k)
            starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
            nonempty = counts > 0
            sums = np.add.reduceat(bits[order], starts[nonempty], axis=0)
            new = words.copy()
            new[nonempty] = np.packbits((2 * sums > counts[nonempty, None]).astype(np.uint8), axis=1)
            empty = np.flatnonzero(~nonempty)          # re-seed empty words with random descriptors
            if len(empty):
                new[empty] = d[rng.choice(len(d), len(empty), replace=False)]
            if np.array_equal(new, words):
                break
            words = new
        return cls(words)

    def histogram(self, descriptors: np.ndarray) -> np.ndarray:
        """Word counts (K,) uint16 of a set of descriptors."""
        if descriptors is None or not len(descriptors):
            return np.zeros(len(self.words), np.uint16)
        labels = [m.trainIdx for m in self._bf.match(np.ascontiguousarray(descriptors), self.words)]
        return np.bincount(labels, minlength=len(self.words)).astype(np.uint16)


class PlaceDatabase:
    """Keyframe descriptors → candidate keyframes for a query (loop closing, relocalisation)."""

    def __init__(self, config: SlamConfig) -> None:
        self.config = config
        self.vocabulary: Vocabulary | None = None
        self.trained_at = 0                      # keyframes the vocabulary was learnt from
        self._lock = threading.RLock()
        self._descriptors: dict[int, np.ndarray] = {}
        self._ids: list[int] = []
        self._hist = np.zeros((0, 0), np.uint16)

    @classmethod
    def restore(cls, config: SlamConfig, vocabulary: Vocabulary | None, ids: list[int], histograms: np.ndarray,
                descriptors: dict[int, np.ndarray]) -> "PlaceDatabase":
        """A database as saved: its vocabulary, the indexed keyframes and their word counts."""
        db = cls(config)
        db.vocabulary = vocabulary
        db._ids = list(ids)
        db._descriptors = {k: descriptors[k] for k in ids}
        db._hist = np.asarray(histograms, np.uint16).reshape(len(ids), -1) if vocabulary is not None else \
            np.zeros((0, 0), np.uint16)
        db.trained_at = len(ids) if vocabulary is not None else 0
        return db

    def __len__(self) -> int:
        return len(self._ids)

    def add(self, kf_id: int, descriptors: np.ndarray) -> None:
        """Index a keyframe; (re)trains the vocabulary when the map has grown enough."""
        with self._lock:
            self._descriptors[kf_id] = descriptors
            self._ids.append(kf_id)
            if self.vocabulary is not None:
                self._hist = np.vstack([self._hist, self.vocabulary.histogram(descriptors)[None]])
            n = len(self._ids)
            due = (self.trained_at == 0 and n >= self.config.vocabulary_first) or \
                  (self.trained_at > 0 and n >= 2 * self.trained_at and n <= RETRAIN_UNTIL)
        if due:
            self.retrain()

    def retrain(self) -> None:
        with self._lock:
            ids = list(self._ids)
            descriptors = np.concatenate([self._descriptors[k] for k in ids]) if ids else np.zeros((0, 32), np.uint8)
        if len(descriptors) < 2:
            return
        vocabulary = Vocabulary.train(descriptors, self.config.vocabulary_words, seed=len(ids))
        hist = np.stack([vocabulary.histogram(self._descriptors[k]) for k in ids])
        with self._lock:
            extra = self._ids[len(ids):]              # added while training
            if extra:
                hist = np.vstack([hist, np.stack([vocabulary.histogram(self._descriptors[k]) for k in extra])])
            self.vocabulary, self._hist, self.trained_at = vocabulary, hist, len(ids)

    def query(self, descriptors: np.ndarray, top: int, exclude: set[int] = frozenset()) -> list[tuple[int, float]]:
        """The ``top`` keyframes most similar to ``descriptors`` as (id, score), best first.
        Without a vocabulary yet (fewer than ``vocabulary_first`` keyframes), every keyframe
        not excluded (score 0)."""
        with self._lock:
            ids, hist, vocabulary = list(self._ids), self._hist, self.vocabulary
        keep = np.array([k not in exclude for k in ids], bool)
        if not keep.any():
            return []
        if vocabulary is None:
            return [(k, 0.0) for k, ok in zip(ids, keep) if ok]
        q = vocabulary.histogram(descriptors).astype(np.float32)
        h = hist.astype(np.float32)
        df = (h > 0).sum(axis=0)
        idf = np.log(len(ids) / np.maximum(df, 1)).astype(np.float32)
        v = h * idf
        v /= np.maximum(v.sum(axis=1, keepdims=True), 1e-12)
        qv = q * idf
        qv /= max(float(qv.sum()), 1e-12)
        scores = 1.0 - 0.5 * np.abs(v - qv).sum(axis=1)
        scores[~keep] = -1.0
        order = np.argsort(-scores)[:top]
        return [(ids[i], float(scores[i])) for i in order if keep[i]]

    def state(self) -> tuple[np.ndarray | None, list[int], np.ndarray]:
        """(vocabulary words, keyframe ids, their histograms) for saving."""
        with self._lock:
            return (None if self.vocabulary is None else self.vocabulary.words.copy(), list(self._ids),
                    self._hist.copy())

    @property
    def nbytes(self) -> int:
        return int(self._hist.nbytes + (self.vocabulary.words.nbytes if self.vocabulary else 0))
