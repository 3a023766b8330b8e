"""Exceptions and warnings that users are meant to see.

The CLI turns :class:`FtcalError` into one line on stderr and exit code 2, so
every message must name the file, column or parameter at fault and say what is
wrong with it.
"""

from __future__ import annotations


class FtcalError(ValueError):
    """Bad input or an impossible request, explained in one sentence.

    Examples
    --------
    >>> from ftcal import CalibrationModel, FtcalError
    >>> try:
    ...     CalibrationModel(degree=0).fit([[0.0], [1.0]], [[0.0], [1.0]])
    ... except FtcalError as error:
    ...     print("refused:", "degree" in str(error))
    refused: True
    """


class _NamesParameters:
    """A message that names parameters as ``{name}``: Python names in ``str()``, flags in the CLI (:meth:`render`)."""

    def __init__(self, parameter, message: str):
        self.parameters = (parameter,) if isinstance(parameter, str) else tuple(parameter)
        self.parameter = self.parameters[0]
        self.template = message
        super().__init__(self.render(lambda name: name))

    def render(self, name_of) -> str:
        """The message with each ``{parameter}`` written as ``name_of(parameter)``."""
        text = self.template
        for name in self.parameters:
            text = text.replace("{" + name + "}", name_of(name))
        return text

    def __reduce__(self):  # pickled across processes (Dask workers) with both arguments
        return type(self), (self.parameters, self.template)


class ParameterError(_NamesParameters, FtcalError):
    """A parameter of a library call is wrong; the message names it by its Python name.

    ``message`` writes each parameter it names as ``{name}`` (``"{degree} must be in 1..10"``):
    ``str(error)`` shows the Python names (``degree must be in 1..10``), and the command line
    shows its flags instead (:meth:`render` with ``ftcal.cli._common.flag_of``), so one
    message serves both.

    Parameters
    ----------
    parameter : str or sequence of str
        The parameter(s) at fault, the first the main one (:attr:`parameter`).
    message : str
        The sentence, with ``{name}`` for each of them.

    Examples
    --------
    >>> error = ParameterError("degree", "{degree} must be in 1..10; got 0.")
    >>> str(error), error.parameter
    ('degree must be in 1..10; got 0.', 'degree')
    >>> error.render(lambda name: "--" + name)
    '--degree must be in 1..10; got 0.'
    """


class NotFittedError(FtcalError):
    """A model method that needs fitted state was called before ``fit``."""


class FtcalWarning(UserWarning):
    """Something the user should know about, that does not stop the work.

    Examples
    --------
    >>> import warnings
    >>> import numpy as np
    >>> from ftcal import CalibrationModel, FtcalWarning
    >>> model = CalibrationModel(1).fit(np.array([[0.0], [1.0], [2.0]]), np.array([[0.0], [2.0], [4.0]]))
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     _ = model.predict(np.array([[5.0]]))  # outside the training range
    >>> any(issubclass(w.category, FtcalWarning) for w in caught)
    True
    """


class ParameterWarning(_NamesParameters, FtcalWarning):
    """A warning about a parameter, named as :class:`ParameterError` names it (``{name}`` in the message)."""


class IllPosedFitWarning(FtcalWarning):
    """The fit is rank-deficient, ill-conditioned or under-determined."""


class IllPosedParameterWarning(ParameterWarning, IllPosedFitWarning):
    """An :class:`IllPosedFitWarning` whose advice names parameters (``{name}``, as :class:`ParameterWarning`)."""


class UndeterminedWarning(IllPosedFitWarning):
    """The data determine only some parameters; the others are held at a stated default and reported undetermined."""


class OutOfRangeWarning(FtcalWarning):
    """Prediction inputs fall outside the range seen during training."""


class PrecisionLossWarning(FtcalWarning):
    """Converting a model to raw-input monomials lost significant digits."""


def single_line(text: str) -> str:
    """``text`` with line breaks and tabs written as escapes: a name from a file (a bag topic, a column,
    a model's input) cannot start a line of its own in the output and forge it.

    Examples
    --------
    >>> single_line("topic\\nwrote model.json")
    'topic\\\\nwrote model.json'
    """
    import re

    return re.sub("[\t\n\x0b\x0c\r\x1c-\x1e\x85\u2028\u2029]",
                  lambda m: m.group(0).encode("unicode_escape").decode("ascii"), str(text))
