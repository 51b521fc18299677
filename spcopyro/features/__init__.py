"""Image features for SpCoMapping from camera images: torchvision's AlexNet with a place head.

* :mod:`~spcopyro.features.backbone`: AlexNet and its weights (torchvision's ImageNet weights
  from its cache, a local checkpoint, or random), with a clear error when they are missing;
* :mod:`~spcopyro.features.images`: finding images, OpenCV decoding, torchvision preprocessing;
* :mod:`~spcopyro.features.head`: the place head over K classes and its fine-tuning (labels or
  distillation), head files;
* :mod:`~spcopyro.features.extract`: batch extraction into Ft.csv rows;
* :mod:`~spcopyro.features.distill`: the distillation report (KL, top-1 agreement);
* :mod:`~spcopyro.features.cli`: the ``spcopyro features`` / ``features-head`` commands.

Names are imported lazily (``from spcopyro.features import extract_to_csv`` works), so that
importing the command line does not import torchvision.
"""

from __future__ import annotations

from spcopyro._util.lazy import lazy_names

_EXPORTS = {
    "backbone": (
        "FEATURE_DIM",
        "IMAGENET_WEIGHTS",
        "CheckpointError",
        "WeightsNotFoundError",
        "WeightsSource",
        "load_alexnet",
        "load_state_dict_file",
        "parse_weights",
        "torchvision_cache_file",
    ),
    "images": (
        "ImageReadError",
        "UnreadableImagesError",
        "iter_image_batches",
        "list_images",
        "make_transform",
        "read_image",
        "read_labelled_images",
    ),
    "head": (
        "HeadFile",
        "PlaceClassifier",
        "TrainingResult",
        "encode_labels",
        "load_head",
        "save_head",
        "train_head",
    ),
    "extract": (
        "ExtractionResult",
        "check_out_file",
        "extract_features",
        "extract_to_csv",
        "frozen_inputs",
        "resolve_device",
        "write_features_csv",
    ),
    "distill": ("DistillationReport", "distillation_report", "kl_divergence", "top1_agreement"),
}
_MODULE_OF = {name: module for module, names in _EXPORTS.items() for name in names}

__all__ = sorted(_MODULE_OF)


__getattr__, __dir__ = lazy_names(__name__, _MODULE_OF)
