"""The warning that a model runs worse on its own while it fits the training dances better."""

from __future__ import annotations

import math

from kinectdata.training.train import WORSE_SMAPE_POINTS, validation_warning


def rows(*epochs: tuple[float | None, float | None]) -> list[dict]:
    return [{"epoch": i + 1, "train_loss": t, "val_smape": v} for i, (t, v) in enumerate(epochs)]


def said_at(history: list[dict]) -> list[int]:
    """The epochs at which the warning is said, run as training runs it (after each epoch's row)."""
    return [history[n - 1]["epoch"] for n in range(1, len(history) + 1) if validation_warning(history[:n])]


def test_said_once_when_the_validation_smape_worsens_while_the_training_loss_halves():
    assert WORSE_SMAPE_POINTS == 1.0
    history = rows(
        (1.0, 20.0),
        (0.6, 19.0),  # the best: 19.0 % at a training loss of 0.6
        (0.4, 19.5),  # 0.5 points worse: not yet
        (0.29, 20.1),  # 1.1 points worse at less than half the loss: said
        (0.25, 20.5),  # the same streak: not again
        (0.2, 19.2),  # recovered
        (0.15, 21.0),  # worse again: said again
        (0.14, 22.0),
    )
    assert said_at(history) == [4, 7]
    message = validation_warning(history[:4])
    assert "20.10 % at epoch 4" in message and "19.00 % at epoch 2" in message
    assert "from 0.6 to 0.29" in message and "--epochs 2" in message


def test_not_said_unless_both_conditions_hold_and_said_at_their_edges():
    # 3 points worse but the training loss only fell to 0.31 of the best epoch's 0.6: not half
    assert said_at(rows((0.6, 19.0), (0.4, 21.0), (0.31, 22.0))) == []
    # the training loss halved, the SMAPE 0.9 points worse
    assert said_at(rows((0.6, 19.0), (0.2, 19.9), (0.1, 19.95))) == []
    # exactly 1.0 point worse at exactly half the loss: said
    assert said_at(rows((0.5, 19.0), (0.25, 20.0))) == [2]
    # a better SMAPE, however small the loss
    assert said_at(rows((0.5, 19.0), (0.01, 18.0))) == []


def test_the_best_earlier_epoch_is_the_lowest_smape_not_the_first_or_the_last():
    history = rows((1.0, 25.0), (0.5, 18.0), (0.4, 24.0), (0.3, 18.9), (0.24, 19.1))
    # epoch 5 is 1.1 points above the best (18.0 at epoch 2, loss 0.5) at less than half of 0.5; it is
    # far below epoch 1's and only 0.2 above epoch 4's
    assert said_at(history) == [5]
    assert "--epochs 2" in validation_warning(history)
    # at less than half of epoch 2's loss but above half: not said
    assert said_at(rows((1.0, 25.0), (0.5, 18.0), (0.4, 24.0), (0.3, 18.9), (0.26, 19.1))) == []


def test_missing_or_not_finite_values_say_nothing():
    nan = math.nan
    assert validation_warning(rows((0.5, 19.0))) is None  # one epoch: nothing earlier
    assert validation_warning(rows((0.5, 19.0), (0.1, None))) is None  # no validation this epoch
    assert validation_warning(rows((0.5, 19.0), (0.1, nan))) is None
    assert validation_warning(rows((0.5, 19.0), (nan, 25.0))) is None
    assert validation_warning(rows((0.5, 19.0), (None, 25.0))) is None
    assert validation_warning(rows((None, None), (None, None))) is None
    assert validation_warning([{"epoch": 1, "train_loss": 0.5}, {"epoch": 2, "train_loss": 0.1}]) is None
    # an epoch without validation is not a best epoch; the finite ones are compared
    assert said_at(rows((0.5, nan), (0.4, 19.0), (0.3, None), (0.15, 20.5))) == [4]


def test_a_free_running_rhythm_loss_rising_while_training_falls_is_said_once():
    from kinectdata.training.train import validation_warning

    train = [3.0, 2.5, 2.2, 2.0, 1.9, 1.8]
    rhythm = [3.0, 2.5, 2.6, 2.7, 2.8, 2.9]
    rows = [
        {"epoch": i + 1, "train_loss": t, "val_smape": 50.0, "val_rhythm": r}
        for i, (t, r) in enumerate(zip(train, rhythm))
    ]
    said = [validation_warning(rows[:n]) for n in range(1, 7)]
    assert said[:4] == [None] * 4 and said[5] is None
    assert said[4] == (
        "the free-running validation rhythm loss rose 3 epochs in a row (2.5 at epoch 2 -> 2.8 at epoch 5) while the "
        "training loss fell: on its own the model dances less like the real dancers; its best epoch is 2 (2.5), which "
        "--keep best keeps"
    )


def test_a_run_judged_by_its_free_runs_rhythm_is_not_warned_of_its_smape():
    """The real-dance recipe's free-running loss matches how the motion moves, not its poses: its
    SMAPE rising is no sign of overfitting, and the rhythm figure (its own warning) keeps the epoch."""
    history = rows((1.0, 20.0), (0.6, 19.0), (0.29, 20.1))
    assert said_at(history) == [3]
    rhythm = [dict(row, val_rhythm=r) for row, r in zip(history, (12.0, 10.0, 9.5))]
    assert said_at(rhythm) == []
    rising = [
        dict(row, val_rhythm=r) for row, r in zip(rows(*[(1.0 - 0.1 * i, 19.0) for i in range(5)]), (9, 8, 9, 10, 11))
    ]
    assert said_at(rising) == [5] and "which --keep best keeps" in validation_warning(rising)
