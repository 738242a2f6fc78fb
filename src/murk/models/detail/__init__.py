"""The detail stage: a learned local residual added to a restoration (:mod:`murk.models.detail.network`; trained by
:mod:`murk.train.detail`)."""

from murk.models.detail.network import DEFAULT_CHANNELS, DILATIONS, DetailNet, load_detail, save_detail

__all__ = ["DEFAULT_CHANNELS", "DILATIONS", "DetailNet", "load_detail", "save_detail"]
