"""Corpus recipes: a local copy of a public dance corpus in, a recordings manifest out.

As in lhotse, a recipe is a plain function, ``prepare_<corpus>(path, **options) ->``
:class:`CorpusManifest`, that reads the user's copy (nothing is downloaded), knows the corpus's
facts (frame rate, unit, axes, joints, how music and motion line up, published splits) and lists
each recording with the reading options that make kinectdata read it right. ``kinectdata prepare
CORPUS PATH -o recordings.yaml`` writes the result; ``build-dataset`` builds from it.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from kinectdata.core.errors import ConfigError
from kinectdata.dataset.recipes.aistpp import prepare_aistpp
from kinectdata.dataset.recipes.bvh_folder import prepare_bvh_folder
from kinectdata.dataset.recipes.finedance import prepare_finedance
from kinectdata.dataset.recipes.manifest import CorpusManifest
from kinectdata.dataset.recipes.tang2018 import prepare_tang2018


@dataclass(frozen=True)
class Recipe:
    """A registered corpus recipe: its function and a line saying what it reads."""

    name: str
    prepare: Callable[..., CorpusManifest]
    description: str

    @property
    def options(self) -> frozenset[str]:
        """The keyword options ``prepare`` takes besides the path."""
        params = inspect.signature(self.prepare).parameters.values()
        return frozenset(p.name for p in params if p.kind is inspect.Parameter.KEYWORD_ONLY)


RECIPES: dict[str, Recipe] = {}


def register_recipe(name: str, prepare: Callable[..., CorpusManifest], description: str) -> None:
    """Make ``prepare`` available as ``prepare_corpus(name, ...)`` and ``kinectdata prepare name``."""
    RECIPES[name] = Recipe(name, prepare, description)


register_recipe(
    "aistpp",
    prepare_aistpp,
    "AIST++ annotations folder (keypoints3d/*.pkl, splits/, ignore_list.txt) + the AIST Dance DB music",
)
register_recipe(
    "finedance", prepare_finedance, "FineDance data folder (motion/*.npy, music_wav/) + its smplx_neu_J_1.npy"
)
register_recipe("bvh-folder", prepare_bvh_folder, "a folder of .bvh files, each with its music beside it")
register_recipe(
    "tang2018",
    prepare_tang2018,
    "Dance with Melody (Tang et al. 2018) repository folder (DANCE_<style>_<n>/ with skeletons.json, config.json, "
    "audio.mp3)",
)


def prepare_corpus(corpus: str, path: str | Path, **options: Any) -> CorpusManifest:
    """Run the recipe registered as ``corpus`` on the local copy at ``path`` (options as it takes)."""
    if corpus not in RECIPES:
        raise ConfigError(f"unknown corpus {corpus!r} (recipes: {', '.join(sorted(RECIPES))})")
    recipe = RECIPES[corpus]
    wrong = sorted(set(options) - recipe.options)
    if wrong:
        raise ConfigError(
            f"option(s) {', '.join(wrong)} do not apply to {corpus} (it takes {', '.join(sorted(recipe.options))})"
        )
    return recipe.prepare(path, **options)


__all__ = [
    "RECIPES",
    "CorpusManifest",
    "Recipe",
    "prepare_aistpp",
    "prepare_bvh_folder",
    "prepare_finedance",
    "prepare_tang2018",
    "prepare_corpus",
    "register_recipe",
]
