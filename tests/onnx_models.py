"""Small ONNX models with the real GroundingDINO / MobileSAM signatures, for tests and benchmarks.

Real weights cannot be downloaded here, so these graphs have the exports' input and output
names, dtypes and dynamic axes but emit planted outputs (constants, or simple functions of
the inputs), which lets a test know exactly which pixels and categories must come out.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import onnx
from onnx import TensorProto, helper, numpy_helper

OPSET = 17
VOCAB = ["[PAD]", "[UNK]", "[CLS]", "[SEP]", "[MASK]", ".", "?", "chair", "table", "door", "trash", "bin",
         "person", "tv", "##s", "cabinet"]


def write_tokenizer(path: Path, vocab: list[str] = VOCAB) -> Path:
    """A BERT-style WordPiece tokenizer.json with [CLS] $A [SEP] post-processing."""
    from tokenizers import Tokenizer, normalizers, pre_tokenizers, processors
    from tokenizers.models import WordPiece

    ids = {t: i for i, t in enumerate(vocab)}
    tok = Tokenizer(WordPiece(ids, unk_token="[UNK]"))
    tok.normalizer = normalizers.BertNormalizer(lowercase=True)
    tok.pre_tokenizer = pre_tokenizers.BertPreTokenizer()
    tok.post_processor = processors.TemplateProcessing(
        single="[CLS] $A [SEP]", special_tokens=[("[CLS]", ids["[CLS]"]), ("[SEP]", ids["[SEP]"])])
    tok.save(str(path))
    return path


def write_vocab(path: Path, vocab: list[str] = VOCAB) -> Path:
    path.write_text("\n".join(vocab) + "\n")
    return path


def _const(name: str, array: np.ndarray):
    return helper.make_node("Constant", [], [name], value=numpy_helper.from_array(array, name + "_v"))


def _save(graph, path: Path) -> Path:
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", OPSET)])
    model.ir_version = 8
    onnx.checker.check_model(model)
    onnx.save(model, str(path))
    return path


def _detector(path: Path, image_input, text_inputs, logits: np.ndarray, boxes: np.ndarray,
              boxes_name: str) -> Path:
    """Planted (1, Q, T) logits and (1, Q, 4) boxes; the logits pass through Identity of a constant."""
    q, t = logits.shape
    nodes = [_const("logits", logits[None].astype(np.float32)),
             _const(boxes_name, boxes[None].astype(np.float32))]
    outputs = [helper.make_tensor_value_info("logits", TensorProto.FLOAT, [1, q, t]),
               helper.make_tensor_value_info(boxes_name, TensorProto.FLOAT, [1, q, 4])]
    graph = helper.make_graph(nodes, "grounding_dino_test", [image_input, *text_inputs], outputs)
    return _save(graph, path)


def grounding_dino_hf(path: Path, logits: np.ndarray, boxes: np.ndarray,
                      static_hw: tuple[int, int] | None = None) -> Path:
    """Hugging Face GroundingDinoForObjectDetection signature (int64 text inputs, pixel_mask)."""
    h, w = static_hw or ("height", "width")
    inputs = [
        helper.make_tensor_value_info("input_ids", TensorProto.INT64, [1, "seq"]),
        helper.make_tensor_value_info("token_type_ids", TensorProto.INT64, [1, "seq"]),
        helper.make_tensor_value_info("attention_mask", TensorProto.INT64, [1, "seq"]),
        helper.make_tensor_value_info("pixel_mask", TensorProto.INT64, [1, h, w]),
    ]
    image = helper.make_tensor_value_info("pixel_values", TensorProto.FLOAT, [1, 3, h, w])
    return _detector(path, image, inputs, logits, boxes, "pred_boxes")


def grounding_dino_original(path: Path, logits: np.ndarray, boxes: np.ndarray, image_name: str = "img",
                            text_len: int | None = None) -> Path:
    """The original repository's export: bool attention_mask / text_token_mask, int64 ids."""
    seq = text_len or "seq"
    inputs = [
        helper.make_tensor_value_info("input_ids", TensorProto.INT64, [1, seq]),
        helper.make_tensor_value_info("attention_mask", TensorProto.BOOL, [1, seq]),
        helper.make_tensor_value_info("position_ids", TensorProto.INT64, [1, seq]),
        helper.make_tensor_value_info("token_type_ids", TensorProto.INT64, [1, seq]),
        helper.make_tensor_value_info("text_token_mask", TensorProto.BOOL, [1, seq, seq]),
    ]
    image = helper.make_tensor_value_info(image_name, TensorProto.FLOAT, [1, 3, "height", "width"])
    return _detector(path, image, inputs, logits, boxes, "boxes")


def sam_encoder(path: Path) -> Path:
    """(1, 3, 1024, 1024) -> image_embeddings (1, 256, 64, 64): channel mean of 16 x 16 cells."""
    nodes = [
        helper.make_node("AveragePool", ["images"], ["pooled"], kernel_shape=[16, 16], strides=[16, 16]),
        helper.make_node("ReduceMean", ["pooled"], ["gray"], axes=[1], keepdims=1),
        _const("shape", np.array([1, 256, 64, 64], dtype=np.int64)),
        helper.make_node("Expand", ["gray", "shape"], ["image_embeddings"]),
    ]
    graph = helper.make_graph(
        nodes, "sam_encoder_test",
        [helper.make_tensor_value_info("images", TensorProto.FLOAT, [1, 3, 1024, 1024])],
        [helper.make_tensor_value_info("image_embeddings", TensorProto.FLOAT, [1, 256, 64, 64])])
    return _save(graph, path)


def sam_encoder_hwc(path: Path) -> Path:
    """samexporter --use-preprocess form: input_image (H, W, 3) raw RGB; constant embedding."""
    nodes = [
        helper.make_node("ReduceMean", ["input_image"], ["m"], keepdims=0),
        _const("shape", np.array([1, 256, 64, 64], dtype=np.int64)),
        helper.make_node("Expand", ["m", "shape"], ["image_embeddings"]),
    ]
    graph = helper.make_graph(
        nodes, "sam_encoder_hwc_test",
        [helper.make_tensor_value_info("input_image", TensorProto.FLOAT, ["h", "w", 3])],
        [helper.make_tensor_value_info("image_embeddings", TensorProto.FLOAT, [1, 256, 64, 64])])
    return _save(graph, path)


def _decoder_inputs():
    return [
        helper.make_tensor_value_info("image_embeddings", TensorProto.FLOAT, [1, 256, 64, 64]),
        helper.make_tensor_value_info("point_coords", TensorProto.FLOAT, [1, "num_points", 2]),
        helper.make_tensor_value_info("point_labels", TensorProto.FLOAT, [1, "num_points"]),
        helper.make_tensor_value_info("mask_input", TensorProto.FLOAT, [1, 1, 256, 256]),
        helper.make_tensor_value_info("has_mask_input", TensorProto.FLOAT, [1]),
        helper.make_tensor_value_info("orig_im_size", TensorProto.FLOAT, [2]),
    ]


def sam_box_decoder(path: Path) -> Path:
    """SamOnnxModel signature whose mask is the prompt box itself, at orig_im_size.

    It undoes SAM's resize (longest side 1024, rounded) from orig_im_size, so the mask
    lands on the original box only if the caller scaled the corners and ordered (H, W)
    right; it is empty unless the labels are (2, 3), SAM's box-corner labels.
    """
    f = np.float32
    nodes = [
        _const("i0", np.array([0], np.int64)), _const("i1", np.array([1], np.int64)),
        _const("i2", np.array([2], np.int64)), _const("c1024", np.array(1024.0, f)),
        _const("half", np.array(0.5, f)), _const("one", np.array(1.0, f)),
        _const("box_labels", np.array([[2.0, 3.0]], f)),
        _const("pos", np.array(10.0, f)), _const("neg", np.array(-10.0, f)),
        helper.make_node("Slice", ["orig_im_size", "i0", "i1"], ["H1"]),
        helper.make_node("Slice", ["orig_im_size", "i1", "i2"], ["W1"]),
        helper.make_node("Squeeze", ["H1", "i0"], ["H"]),
        helper.make_node("Squeeze", ["W1", "i0"], ["W"]),
        helper.make_node("Max", ["H", "W"], ["L"]),
        helper.make_node("Div", ["c1024", "L"], ["scale"]),
        helper.make_node("Mul", ["H", "scale"], ["Hs"]),
        helper.make_node("Add", ["Hs", "half"], ["Hs5"]),
        helper.make_node("Floor", ["Hs5"], ["newH"]),
        helper.make_node("Mul", ["W", "scale"], ["Ws"]),
        helper.make_node("Add", ["Ws", "half"], ["Ws5"]),
        helper.make_node("Floor", ["Ws5"], ["newW"]),
        helper.make_node("Div", ["W", "newW"], ["sx"]),
        helper.make_node("Div", ["H", "newH"], ["sy"]),
        helper.make_node("Unsqueeze", ["sx", "i0"], ["sx1"]),
        helper.make_node("Unsqueeze", ["sy", "i0"], ["sy1"]),
        helper.make_node("Concat", ["sx1", "sy1"], ["sxy"], axis=0),
        helper.make_node("Mul", ["point_coords", "sxy"], ["pts"]),  # (1, 2, 2) original pixels
        helper.make_node("Reshape", ["pts", "shape4"], ["p4"]),
        _const("shape4", np.array([4], np.int64)),
        _const("idx0", np.array(0, np.int64)), _const("idx1", np.array(1, np.int64)),
        _const("idx2", np.array(2, np.int64)), _const("idx3", np.array(3, np.int64)),
        helper.make_node("Gather", ["p4", "idx0"], ["x0"]),
        helper.make_node("Gather", ["p4", "idx1"], ["y0"]),
        helper.make_node("Gather", ["p4", "idx2"], ["x1"]),
        helper.make_node("Gather", ["p4", "idx3"], ["y1"]),
        helper.make_node("Range", ["half", "W", "one"], ["xs"]),
        helper.make_node("Range", ["half", "H", "one"], ["ys"]),
        helper.make_node("GreaterOrEqual", ["xs", "x0"], ["gx0"]),
        helper.make_node("LessOrEqual", ["xs", "x1"], ["lx1"]),
        helper.make_node("And", ["gx0", "lx1"], ["inx"]),
        helper.make_node("GreaterOrEqual", ["ys", "y0"], ["gy0"]),
        helper.make_node("LessOrEqual", ["ys", "y1"], ["ly1"]),
        helper.make_node("And", ["gy0", "ly1"], ["iny"]),
        helper.make_node("Unsqueeze", ["iny", "i1"], ["iny2"]),
        helper.make_node("Unsqueeze", ["inx", "i0"], ["inx2"]),
        helper.make_node("And", ["iny2", "inx2"], ["inside"]),
        helper.make_node("Equal", ["point_labels", "box_labels"], ["lab_eq"]),
        helper.make_node("Cast", ["lab_eq"], ["lab_f"], to=TensorProto.FLOAT),
        helper.make_node("ReduceMin", ["lab_f"], ["lab_ok_f"], keepdims=0),
        helper.make_node("Cast", ["lab_ok_f"], ["lab_ok"], to=TensorProto.BOOL),
        helper.make_node("And", ["inside", "lab_ok"], ["inside_ok"]),
        helper.make_node("Where", ["inside_ok", "pos", "neg"], ["m2"]),
        _const("axes01", np.array([0, 1], np.int64)),
        helper.make_node("Unsqueeze", ["m2", "axes01"], ["masks"]),
        _const("iou_predictions", np.array([[0.9]], f)),
        _const("low_res_masks", np.zeros((1, 1, 256, 256), f)),
    ]
    nodes = _toposort(nodes)
    outputs = [helper.make_tensor_value_info("masks", TensorProto.FLOAT, [1, 1, "H", "W"]),
               helper.make_tensor_value_info("iou_predictions", TensorProto.FLOAT, [1, 1]),
               helper.make_tensor_value_info("low_res_masks", TensorProto.FLOAT, [1, 1, 256, 256])]
    return _save(helper.make_graph(nodes, "sam_box_decoder_test", _decoder_inputs(), outputs), path)


def sam_lowres_decoder(path: Path, low_res: np.ndarray, iou: np.ndarray) -> Path:
    """SamOnnxModel signature returning planted (N, 256, 256) logits as ``masks`` with IoUs (N,)."""
    n = low_res.shape[0]
    nodes = [_const("masks", low_res[None].astype(np.float32)),
             _const("iou_predictions", iou[None].astype(np.float32)),
             _const("low_res_masks", low_res[None].astype(np.float32))]
    outputs = [helper.make_tensor_value_info("masks", TensorProto.FLOAT, [1, n, 256, 256]),
               helper.make_tensor_value_info("iou_predictions", TensorProto.FLOAT, [1, n]),
               helper.make_tensor_value_info("low_res_masks", TensorProto.FLOAT, [1, n, 256, 256])]
    return _save(helper.make_graph(nodes, "sam_lowres_decoder_test", _decoder_inputs(), outputs), path)


def _toposort(nodes):
    """Order nodes so every input is produced first (graph inputs count as produced)."""
    produced = {"orig_im_size", "point_coords", "point_labels", "image_embeddings", "mask_input",
                "has_mask_input"}
    ordered, pending = [], list(nodes)
    while pending:
        progress = False
        for node in list(pending):
            if all(i in produced for i in node.input):
                ordered.append(node)
                produced.update(node.output)
                pending.remove(node)
                progress = True
        if not progress:
            raise ValueError(f"cannot order nodes: {[n.op_type for n in pending]}")
    return ordered
