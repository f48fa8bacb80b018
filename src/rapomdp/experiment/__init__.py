"""The closed loop (paper Sec. 5.2): episodes, the methods compared, metrics, figures, report.

Importing this package registers the gymnasium environment :data:`ENV_ID`
(:class:`rapomdp.experiment.env.ActiveRecognitionEnv`, built lazily by ``gymnasium.make``).
"""

ENV_ID = "rapomdp/ActiveRecognition-v0"


def _register_env() -> None:
    import gymnasium

    if ENV_ID not in gymnasium.registry:
        gymnasium.register(ENV_ID, entry_point="rapomdp.experiment.env:make_env")


_register_env()
