"""Exceptions raised by the engine. Messages name the offending value and what was expected."""


class InputError(ValueError):
    """A parameter or model input is outside its physical/valid domain."""


class InstabilityError(RuntimeError):
    """The run blew up (non-finite or runaway velocity); names the step and the ball."""

    def __init__(self, message: str, step: int, ball: int):
        super().__init__(message)
        self.step = step
        self.ball = ball
