"""``rapomdp pretrain``: build the corpus, pretrain the depth backbone, write it with its card."""

from __future__ import annotations

from functools import partial
from pathlib import Path
from typing import Annotated

import typer
from rich.markup import escape

from rapomdp.cli.common import _fail, _guard, console


def pretrain(
    workdir: Annotated[Path, typer.Option(
        "--workdir", "-d", metavar="DIR",
        help="The pretraining folder: corpus/, views.npz, the checkpoint (kept between "
             "runs: a stopped run resumes).")] = Path("runs/pretrain"),
    out: Annotated[Path | None, typer.Option(
        "--out", "-o", metavar="FILE",
        help="The backbone's weights file (.pt; its card is written beside it as .json). "
             "Default: DIR/depth-backbone.pt. To rebuild the one the package ships: "
             "src/rapomdp/recognition/weights/depth-backbone-v1.pt.")] = None,
    epochs: Annotated[int, typer.Option(min=1, help="Passes over the corpus views.")] = 10,
    families: Annotated[int, typer.Option(min=0, help="Abstract shape families (classes) "
                                          "in the corpus.")] = 160,
    models: Annotated[int, typer.Option(min=1, help="Models of each abstract family.")] = 20,
    kicad: Annotated[bool, typer.Option(
        help="Add the kicad-packages3d classes that are in no evaluation set (a 379 MB "
             "download with apt-get, or --deb).")] = True,
    deb: Annotated[Path | None, typer.Option(help="A downloaded kicad-packages3d .deb.")
                   ] = None,
    extra: Annotated[list[Path] | None, typer.Option(
        help="More mesh folders (CLASS/MODEL.EXT); an evaluation class or a held-back "
             "source is refused. Repeatable.")] = None,
    views: Annotated[int, typer.Option(min=1, help="Views per corpus model.")] = 24,
    seed: Annotated[int, typer.Option(min=0, help="Weights, batch order, validation split.")
                    ] = 0,
    workers: Annotated[int, typer.Option(min=1, help="Processes rendering the corpus.")] = 2,
    threads: Annotated[int | None, typer.Option(
        min=1, help="PyTorch's CPU threads (default: half the cores).")] = None,
    device: Annotated[str, typer.Option(help="auto (CUDA when available), cpu or cuda.")
                      ] = "auto",
    restart: Annotated[bool, typer.Option(help="Forget the checkpoint and train from the "
                                          "first epoch.")] = False,
    stop_after: Annotated[int | None, typer.Option(
        min=1, help="Stop after this many epochs of this run (run again to resume).")] = None,
    progress: Annotated[bool, typer.Option(help="Progress bars.")] = True,
) -> None:
    """Pretrain the depth backbone the train stage fine-tunes (``train.backbone``).

    Builds a corpus of many classes, none of them a class of an evaluation set (abstract
    shape families made here and electronic components from Debian's kicad-packages3d; never
    a sweethome3d* package), renders and preprocesses it as the pipeline does, trains the
    pipeline's network on it with a checkpoint after every epoch, and writes the
    convolutions' weights with a model card (corpus, recipe, seconds). Each step is kept when
    already done; a stopped run resumes from its last epoch. Under an hour on 2 CPU cores at
    the defaults (docs/recognition.md).
    """
    from rapomdp.data.build import DatasetBuildError
    from rapomdp.pretrain import CorpusSettings, PretrainSettings, ViewSettings, run_pretrain

    if device not in ("auto", "cpu", "cuda"):
        raise _fail(f"--device must be auto, cpu or cuda, got {device!r}")
    if out is not None and out.suffix != ".pt":
        raise _fail(f"--out {out}: a backbone's weights file ends in .pt")

    def log(line: str) -> None:
        console.print(escape(line), highlight=False, soft_wrap=True)

    try:
        _guard(partial(
            run_pretrain, workdir, out,
            CorpusSettings(families, models, kicad, deb=deb, extra=tuple(extra or ())),
            ViewSettings(views=views, seed=seed), PretrainSettings(epochs=epochs, seed=seed),
            workers, threads, device, restart, stop_after, progress, log))
    except DatasetBuildError as exc:
        raise _fail(str(exc)) from None
