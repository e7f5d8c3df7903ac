"""Text prompts for GroundingDINO: caption, BERT tokens, per-category spans, phrase masks.

GroundingDINO scores every query against every *token* of one caption that lists all the
categories ("chair . table . door ."). To turn token scores back into categories we need
which token positions belong to which category (spans from character offsets), and the
original repository's export also wants the sub-sentence inputs the model computes from
the "." separators: a block-diagonal self-attention mask per phrase and position ids that
restart in each phrase (its ``generate_masks_with_special_tokens_and_transfer_map``).
Tokenization uses the ``tokenizers`` library with the model's tokenizer.json or a BERT
vocab.txt, so no transformers install is needed at run time.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from bomc_bt.errors import BomcError

CLS, SEP, PAD, DOT, QUESTION = "[CLS]", "[SEP]", "[PAD]", ".", "?"


@dataclass
class TokenizedPrompt:
    """One caption as model inputs (each (1, L)), plus which tokens belong to which category.

    ``category_tokens`` is bool (C, L): row c marks the word-piece tokens of category c
    (not the separators). ``text_mask`` (1, L, L) and ``position_ids`` are the original
    export's sub-sentence inputs; the Hugging Face export derives them itself.
    """

    caption: str
    categories: list[str]
    input_ids: np.ndarray
    attention_mask: np.ndarray
    token_type_ids: np.ndarray
    position_ids: np.ndarray
    text_mask: np.ndarray
    category_tokens: np.ndarray

    @property
    def length(self) -> int:
        return int(self.input_ids.shape[1])


def normalise_category(category: str, file: str | Path | None = None) -> str:
    """Lower-case, single-spaced phrase; '.' would split it into two phrases, so reject it."""
    phrase = " ".join(category.lower().split())
    if not phrase:
        raise BomcError("empty category name", file, "prompts")
    if DOT in phrase:
        raise BomcError(f"category {category!r} contains '.', which separates categories in the "
                        "GroundingDINO prompt", file, "prompts")
    return phrase


def build_caption(categories: list[str]) -> tuple[str, list[tuple[int, int]]]:
    """The GroundingDINO caption ("chair . table .") and each category's character span."""
    parts: list[str] = []
    spans: list[tuple[int, int]] = []
    pos = 0
    for phrase in categories:
        spans.append((pos, pos + len(phrase)))
        parts.append(f"{phrase} {DOT}")
        pos += len(phrase) + 3  # phrase + " ." + " "
    return " ".join(parts), spans


class PromptTokenizer:
    """A BERT word-piece tokenizer loaded from tokenizer.json or vocab.txt."""

    def __init__(self, path: str | Path):
        self.path = Path(path)
        self._tok = _load(self.path)
        self._tok.no_padding()
        self._tok.no_truncation()
        ids = {t: self._tok.token_to_id(t) for t in (CLS, SEP, DOT)}
        missing = [t for t, i in ids.items() if i is None]
        if missing:
            raise BomcError(f"tokenizer vocabulary lacks {', '.join(missing)} (not a BERT tokenizer?)",
                            self.path)
        self.cls_id, self.sep_id, self.dot_id = ids[CLS], ids[SEP], ids[DOT]
        pad = self._tok.token_to_id(PAD)
        self.pad_id = 0 if pad is None else pad
        q = self._tok.token_to_id(QUESTION)
        self.separator_ids = [i for i in (self.cls_id, self.sep_id, self.dot_id, q) if i is not None]

    def encode(self, categories: list[str], length: int | None = None) -> TokenizedPrompt:
        """Tokenize the caption for ``categories``; pad to ``length`` when the export fixed it."""
        phrases = [normalise_category(c) for c in categories]
        caption, spans = build_caption(phrases)
        enc = self._tok.encode(caption)
        ids = np.asarray(enc.ids, dtype=np.int64)
        offsets = np.asarray(enc.offsets, dtype=np.int64).reshape(-1, 2)
        special = np.asarray(enc.special_tokens_mask, dtype=bool)
        if ids.size == 0 or ids[0] != self.cls_id:  # tokenizer without BERT's post-processor
            ids, offsets, special = _wrap(ids, offsets, special, self.cls_id, self.sep_id)
        n = ids.size
        if length is not None:
            if n > length:
                raise BomcError(f"the prompt needs {n} tokens but the model takes {length}; "
                                "use fewer or shorter categories", field="prompts")
            pad = length - n
            ids = np.concatenate([ids, np.full(pad, self.pad_id, np.int64)])
            offsets = np.concatenate([offsets, np.zeros((pad, 2), np.int64)])
            special = np.concatenate([special, np.ones(pad, bool)])
        attention = (np.arange(ids.size) < n).astype(np.int64)
        text_mask, position_ids = phrase_masks(ids, self.separator_ids)
        return TokenizedPrompt(
            caption=caption,
            categories=list(categories),
            input_ids=ids[None],
            attention_mask=attention[None],
            token_type_ids=np.zeros((1, ids.size), np.int64),
            position_ids=position_ids[None],
            text_mask=text_mask[None],
            category_tokens=category_token_map(offsets, special, spans),
        )


def category_token_map(offsets: np.ndarray, special: np.ndarray, spans: list[tuple[int, int]]) -> np.ndarray:
    """bool (C, L): token l belongs to category c when its characters lie inside c's span."""
    s = np.asarray(spans, dtype=np.int64).reshape(-1, 2)
    starts, ends = offsets[:, 0], offsets[:, 1]
    inside = (starts[None] >= s[:, :1]) & (ends[None] <= s[:, 1:]) & (ends > starts)[None]
    return inside & ~special[None]


def phrase_masks(ids: np.ndarray, separator_ids: list[int]) -> tuple[np.ndarray, np.ndarray]:
    """Block-diagonal self-attention mask (L, L) and per-phrase position ids (L,).

    Mirrors the original GroundingDINO: every token between two separators (the phrase and
    its closing '.') attends only within that block and counts positions from 0; [CLS],
    the last token and padding attend to themselves only with position 0.
    """
    n = ids.size
    mask = np.eye(n, dtype=bool)
    pos = np.zeros(n, dtype=np.int64)
    cols = np.flatnonzero(np.isin(ids, separator_ids))
    previous = 0
    for col in cols:
        if 0 < col < n - 1:
            mask[previous + 1 : col + 1, previous + 1 : col + 1] = True
            pos[previous + 1 : col + 1] = np.arange(col - previous)
        previous = col
    return mask, pos


def _wrap(ids, offsets, special, cls_id: int, sep_id: int):
    ids = np.concatenate([[cls_id], ids, [sep_id]]).astype(np.int64)
    offsets = np.concatenate([np.zeros((1, 2), np.int64), offsets, np.zeros((1, 2), np.int64)])
    special = np.concatenate([[True], special, [True]])
    return ids, offsets, special


def _load(path: Path):
    try:
        from tokenizers import Tokenizer
        from tokenizers.implementations import BertWordPieceTokenizer
    except ImportError:  # pragma: no cover - depends on the install
        raise BomcError("the 'tokenizers' package is needed for GroundingDINO prompts "
                        "(pip install tokenizers)", path) from None
    if not path.is_file():
        raise BomcError("tokenizer file not found", path, "tokenizer")
    try:
        if path.suffix == ".json":
            return Tokenizer.from_file(str(path))
        if path.suffix == ".txt":
            return BertWordPieceTokenizer(str(path), lowercase=True)
    except Exception as exc:  # tokenizers raises plain Exception subclasses on bad files
        raise BomcError(f"cannot load tokenizer: {str(exc).splitlines()[0] if str(exc) else exc}",
                        path, "tokenizer") from None
    raise BomcError("tokenizer must be a tokenizer.json or a BERT vocab.txt", path, "tokenizer")
