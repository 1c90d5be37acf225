"""A trained network as it ships: the bundle folder, what it says about itself, and the model
it loads into.

==============  ==============================================================================
``store``       the files (config, variables, training data), written whole, fingerprinted
``whitening``   the descriptor whitenings a bundle carries, fitted per frame source
``model_card``  MODEL_CARD.md and the weights index, generated from the files
``inference``   :class:`~sphere_jax.bundles.inference.Bundle`: load one, orient or describe
==============  ==============================================================================

Training writes bundles (:mod:`sphere_jax.training`) and decides how a run starts from one
(:mod:`sphere_jax.training.warm_start`); everything here sits below the descriptors, training
and the evaluations, and imports none of them.
"""
