"""
Diffusion Policy (Chi et al., RSS 2023) as a robomimic 0.3.0 algorithm, ``diffusion_policy``, in the design robomimic
0.5 ships: a FiLM-conditioned 1D temporal U-Net (veragmil_suite.learning.algos.conditional_unet1d) predicts the
noise of an action sequence given the observations of the last steps; the noise schedulers (DDPM, DDIM) and the
exponential moving average of the weights are the ``diffusers`` package's.

Training: robomimic's SequenceDataset gives each sample ``frame_stack - 1`` steps before its index and
``seq_length`` steps from it, observations and actions alike. The first ``observation_horizon`` observations
(frame_stack of them) condition the network; the first ``prediction_horizon`` actions (frame_stack - 1 + seq_length
of them) are noised at a random diffusion step, and the network learns to predict that noise (mean squared error).
The action window thus starts at the oldest observation, as in the paper.

Acting: from the newest ``observation_horizon`` observations, the policy denoises a ``prediction_horizon``-step
action sequence from Gaussian noise (the enabled scheduler, ``num_inference_timesteps`` steps) and executes
``action_horizon`` of its actions from the one that follows the newest observation, before predicting again (action
chunking). The observation history comes from robomimic's FrameStackWrapper when robomimic wraps the env (its train
loop, run_trained_agent); given one observation per call (veragmil_suite.evaluation.agents), the policy keeps it
itself, starting an episode with its first observation repeated, as the wrapper and the dataset's frame padding do.
"""

from __future__ import annotations

import copy
import warnings
from collections import OrderedDict, deque
from typing import TYPE_CHECKING

import robomimic.models.obs_nets as ObsNets
import robomimic.utils.obs_utils as ObsUtils
import robomimic.utils.tensor_utils as TensorUtils
import robomimic.utils.torch_utils as TorchUtils
import torch
import torch.nn.functional as F
from robomimic.algo import PolicyAlgo, register_algo_factory_func
from torch import nn

from veragmil_suite.learning.algos import diffusion_policy_config  # noqa: F401 - registers the config
from veragmil_suite.learning.algos.conditional_unet1d import ConditionalUnet1D

if TYPE_CHECKING:
    from robomimic.config.config import Config


@register_algo_factory_func("diffusion_policy")
def algo_config_to_class(algo_config: Config) -> tuple[type[DiffusionPolicyUNet], dict]:
    """
    Maps the algo config to the Diffusion Policy class to instantiate, with its keyword arguments.

    Args:
        algo_config (Config instance): algo config

    Returns:
        algo_class: subclass of Algo
        algo_kwargs (dict): dictionary of additional kwargs to pass to algorithm
    """
    if not algo_config.unet.enabled:
        raise ValueError("diffusion_policy has one noise prediction network, the U-Net: set algo.unet.enabled")
    return DiffusionPolicyUNet, {}


def _groupnorm_instead_of_batchnorm(module: nn.Module) -> nn.Module:
    """Every BatchNorm2d of ``module`` (robomimic's ResNet image encoders) replaced by a GroupNorm of 16 channels per
    group: batch statistics and an EMA of the weights do not mix (robomimic 0.5 does the same)."""
    for name, child in module.named_children():
        if isinstance(child, nn.BatchNorm2d):
            setattr(module, name, nn.GroupNorm(max(1, child.num_features // 16), child.num_features))
        else:
            _groupnorm_instead_of_batchnorm(child)
    return module


class DiffusionPolicyUNet(PolicyAlgo):
    """Diffusion Policy with a 1D temporal U-Net (see the module docstring)."""

    def _create_networks(self):
        """
        Creates networks and places them into @self.nets: the observation encoder and the noise prediction net
        (``self.nets["policy"]``, the one the optimizer trains), its EMA copy for acting, and the noise scheduler.
        """
        horizon = self.algo_config.horizon
        self._check_horizons(horizon)
        encoder = ObsNets.ObservationGroupEncoder(
            observation_group_shapes=OrderedDict(obs=OrderedDict(self.obs_shapes)),
            encoder_kwargs=ObsUtils.obs_encoder_kwargs_from_config(self.obs_config.encoder),
        )
        encoder = _groupnorm_instead_of_batchnorm(encoder)
        unet = self.algo_config.unet
        noise_pred_net = ConditionalUnet1D(
            input_dim=self.ac_dim,
            global_cond_dim=encoder.output_shape()[0] * horizon.observation_horizon,
            diffusion_step_embed_dim=unet.diffusion_step_embed_dim,
            down_dims=tuple(unet.down_dims),
            kernel_size=unet.kernel_size,
            n_groups=unet.n_groups,
        )
        self.nets = nn.ModuleDict({"policy": nn.ModuleDict({"obs_encoder": encoder, "noise_pred_net": noise_pred_net})})
        self.nets = self.nets.float().to(self.device)
        self.noise_scheduler, self.num_inference_timesteps = self._make_noise_scheduler()

        self.ema = None
        self._ema_nets = None  # the EMA weights in a copy of the nets, brought up to date when acting
        if self.algo_config.ema.enabled:
            with warnings.catch_warnings():
                # diffusers.training_utils imports all of diffusers' models; on a machine without CUDA one of them
                # warns at import that it disables its autocast: about a model this policy never uses
                warnings.filterwarnings("ignore", "CUDA is not available or torch_xla is imported", UserWarning)
                from diffusers.training_utils import EMAModel  # heavy: diffusers, only when used

            # the paper's EMA: decay 1 - (1 + step)^-power, at most 0.9999
            power = self.algo_config.ema.power
            # foreach: one fused update of all weights, where a loop launches kernels weight by weight
            self.ema = EMAModel(
                self.nets.parameters(), decay=0.9999, use_ema_warmup=True, inv_gamma=1.0, power=power, foreach=True
            )
            self._ema_nets = copy.deepcopy(self.nets).eval().requires_grad_(False)
            self._ema_current = False
        self._actions = deque()  # the executed part of the last prediction, not yet taken
        self._history = None  # observation key -> deque of the last observation_horizon observations [B, ...]
        self._checked_action_range = False

    def _check_horizons(self, horizon) -> None:
        """The dataset's windows must match the horizons: ValueError naming the train settings that do."""
        stack, seq = self.global_config.train.frame_stack, self.global_config.train.seq_length
        to, ta, tp = horizon.observation_horizon, horizon.action_horizon, horizon.prediction_horizon
        if not 1 <= ta <= tp - to + 1:
            raise ValueError(
                f"action_horizon {ta} must be at least 1 and leave the prediction_horizon ({tp}) room for the "
                f"observation_horizon ({to}): at most {tp - to + 1}"
            )
        if stack != to or stack - 1 + seq != tp:
            raise ValueError(
                f"diffusion_policy trains on windows of observation_horizon ({to}) observations and prediction_horizon "
                f"({tp}) actions: set train.frame_stack = {to} and train.seq_length = {tp - to + 1} "
                f"(got {stack} and {seq})"
            )

    def _make_noise_scheduler(self):
        """The enabled one of the config's DDPM and DDIM schedulers, and its number of denoising steps."""
        ddpm, ddim = self.algo_config.ddpm, self.algo_config.ddim
        if ddpm.enabled == ddim.enabled:
            raise ValueError("diffusion_policy needs exactly one of algo.ddpm.enabled and algo.ddim.enabled")
        if ddpm.enabled:
            from diffusers.schedulers.scheduling_ddpm import DDPMScheduler  # heavy: diffusers, only when used

            scheduler = DDPMScheduler(
                num_train_timesteps=ddpm.num_train_timesteps,
                beta_schedule=ddpm.beta_schedule,
                clip_sample=ddpm.clip_sample,
                prediction_type=ddpm.prediction_type,
            )
            return scheduler, ddpm.num_inference_timesteps
        from diffusers.schedulers.scheduling_ddim import DDIMScheduler  # heavy: diffusers, only when used

        scheduler = DDIMScheduler(
            num_train_timesteps=ddim.num_train_timesteps,
            beta_schedule=ddim.beta_schedule,
            clip_sample=ddim.clip_sample,
            set_alpha_to_one=ddim.set_alpha_to_one,
            steps_offset=ddim.steps_offset,
            prediction_type=ddim.prediction_type,
        )
        return scheduler, ddim.num_inference_timesteps

    def _create_optimizers(self):
        """robomimic's optimizers (AdamW here); a cosine learning rate schedule with warm-up, stepped every batch
        over the run's gradient steps (train.num_epochs x experiment.epoch_every_n_steps), replaces robomimic's
        epoch schedulers when the config asks for it."""
        super()._create_optimizers()
        lr = self.optim_params["policy"]["learning_rate"]
        if lr.get("scheduler_type") != "cosine":
            return
        from diffusers.optimization import get_cosine_schedule_with_warmup  # heavy: diffusers, only when used

        steps_per_epoch = self.global_config.experiment.epoch_every_n_steps
        if not steps_per_epoch:
            raise ValueError(
                "the cosine learning rate schedule spans the run's gradient steps: set experiment.epoch_every_n_steps"
            )
        self.lr_schedulers["policy"] = get_cosine_schedule_with_warmup(
            self.optimizers["policy"],
            num_warmup_steps=lr["warmup_steps"],
            num_training_steps=self.global_config.train.num_epochs * steps_per_epoch,
            num_cycles=lr["num_cycles"],
        )

    def _steps_every_batch(self) -> bool:
        return bool(self.optim_params["policy"]["learning_rate"].get("step_every_batch", False))

    def process_batch_for_training(self, batch: dict) -> dict:
        """
        The first observation_horizon observations and prediction_horizon actions of each sample.

        Args:
            batch (dict): dictionary with torch.Tensors sampled from a data loader

        Returns:
            input_batch (dict): processed and filtered batch that will be used for training
        """
        horizon = self.algo_config.horizon
        input_batch = dict(
            obs={k: batch["obs"][k][:, : horizon.observation_horizon] for k in batch["obs"]},
            goal_obs=batch.get("goal_obs", None),
            actions=batch["actions"][:, : horizon.prediction_horizon],
        )
        if not self._checked_action_range:
            # the schedulers clip denoised samples to [-1, 1]: actions outside it could never be produced
            outside = (input_batch["actions"].abs() > 1).any().item()
            if outside:
                raise ValueError("diffusion_policy needs actions within [-1, 1]; the dataset's exceed it")
            self._checked_action_range = True
        return TensorUtils.to_float(TensorUtils.to_device(input_batch, self.device))

    def _conditioning(self, nets: nn.ModuleDict, obs: dict) -> torch.Tensor:
        """The observations [B, observation_horizon, ...] encoded and flattened to [B, features x horizon]."""
        features = TensorUtils.time_distributed({"obs": obs}, nets["policy"]["obs_encoder"], inputs_as_kwargs=True)
        return features.flatten(start_dim=1)

    def train_on_batch(self, batch: dict, epoch: int, validate: bool = False) -> dict:
        """
        Training on a single batch of data: the noise prediction loss at random diffusion steps.

        Args:
            batch (dict): dictionary with torch.Tensors sampled from a data loader and filtered by
                @process_batch_for_training
            epoch (int): epoch number
            validate (bool): if True, don't perform any learning updates.

        Returns:
            info (dict): dictionary of relevant inputs, outputs, and losses that might be relevant for logging
        """
        with TorchUtils.maybe_no_grad(no_grad=validate):
            info = super().train_on_batch(batch, epoch, validate=validate)
            actions = batch["actions"]
            cond = self._conditioning(self.nets, batch["obs"])
            noise = torch.randn_like(actions)
            steps = torch.randint(
                0, self.noise_scheduler.config.num_train_timesteps, (actions.shape[0],), device=self.device
            )
            noisy = self.noise_scheduler.add_noise(actions, noise, steps)
            prediction = self.nets["policy"]["noise_pred_net"](noisy, steps, global_cond=cond)
            target = noise if self.noise_scheduler.config.prediction_type == "epsilon" else actions
            loss = F.mse_loss(prediction, target)
            info["losses"] = {"l2_loss": loss}
            if not validate:
                info["policy_grad_norms"] = self._backprop(loss)
                if self._steps_every_batch() and self.lr_schedulers["policy"] is not None:
                    self.lr_schedulers["policy"].step()
                if self.ema is not None:
                    self.ema.step(self.nets.parameters())
                    self._ema_current = False
        return info

    def _backprop(self, loss: torch.Tensor) -> torch.Tensor:
        """
        robomimic's ``backprop_for_loss`` with the squared gradient norm summed where the weights are: robomimic reads
        each weight's norm back to the host, a GPU synchronization per weight tensor (hundreds a step in the U-Net).
        """
        optim = self.optimizers["policy"]
        optim.zero_grad()
        loss.backward()
        grads = [p.grad for p in self.nets.parameters() if p.grad is not None]
        squared_norm = torch.nn.utils.get_total_norm(grads, norm_type=2.0) ** 2
        optim.step()
        return squared_norm.detach()

    def log_info(self, info: dict) -> dict:
        """
        Process info dictionary from @train_on_batch to summarize information to pass to tensorboard for logging.

        Args:
            info (dict): dictionary of info

        Returns:
            loss_log (dict): name -> summary statistic
        """
        log = super().log_info(info)
        log["Loss"] = info["losses"]["l2_loss"].item()
        if "policy_grad_norms" in info:
            log["Policy_Grad_Norms"] = info["policy_grad_norms"].item()
        return log

    def on_epoch_end(self, epoch: int) -> None:
        """Steps robomimic's epoch schedulers; a schedule stepped every batch is stepped in train_on_batch."""
        if not self._steps_every_batch():
            super().on_epoch_end(epoch)

    def _acting_nets(self) -> nn.ModuleDict:
        """The EMA weights when there is an EMA (copied into their nets once per change), else the trained ones."""
        if self.ema is None:
            return self.nets
        if not self._ema_current:
            self.ema.copy_to(self._ema_nets.parameters())
            self._ema_current = True
        return self._ema_nets

    def reset(self) -> None:
        """Starts an episode: no actions queued, no observations seen."""
        self._actions.clear()
        self._history = None

    def _observation_window(self, obs_dict: dict) -> dict:
        """
        The last observation_horizon observations [B, horizon, ...] per key: those of a stacked observation (keys
        shaped [B, T, ...], from robomimic's FrameStackWrapper), else this observation added to the policy's own
        history (keys shaped [B, ...]).
        """
        horizon = self.algo_config.horizon.observation_horizon
        window = {}
        for key, shape in self.obs_shapes.items():
            value = obs_dict[key]
            if value.dim() == len(shape) + 2:
                if value.shape[1] < horizon:  # fewer frames than the horizon: the oldest repeated
                    value = torch.cat([value[:, :1]] * (horizon - value.shape[1]) + [value], dim=1)
                window[key] = value[:, -horizon:]
            elif value.dim() == len(shape) + 1:
                if self._history is None:
                    self._history = {}
                if key not in self._history:
                    self._history[key] = deque([value] * horizon, maxlen=horizon)
                else:
                    self._history[key].append(value)
                window[key] = torch.stack(list(self._history[key]), dim=1)
            else:
                raise ValueError(f"observation {key!r} of shape {tuple(value.shape)} is not [B, {shape}] nor stacked")
        return window

    @torch.no_grad()
    def sample_actions(self, obs: dict) -> torch.Tensor:
        """
        Denoises prediction_horizon actions [B, prediction_horizon, action] from Gaussian noise, given the
        observations [B, observation_horizon, ...] (torch's global generator draws the noise).
        """
        nets = self._acting_nets()
        cond = self._conditioning(nets, obs)
        tp = self.algo_config.horizon.prediction_horizon
        actions = torch.randn((cond.shape[0], tp, self.ac_dim), device=self.device)
        self.noise_scheduler.set_timesteps(self.num_inference_timesteps)
        for step in self.noise_scheduler.timesteps:
            prediction = nets["policy"]["noise_pred_net"](actions, step, global_cond=cond)
            actions = self.noise_scheduler.step(prediction, step, actions).prev_sample
        return actions

    def get_action(self, obs_dict: dict, goal_dict: dict | None = None) -> torch.Tensor:
        """
        Get policy action outputs: the next queued action, after predicting a new chunk when the queue is empty.

        Args:
            obs_dict (dict): current observation [B, ...], or the stacked last ones [B, T, ...]
            goal_dict (dict): (optional) goal

        Returns:
            action (torch.Tensor): action tensor [B, action]
        """
        window = self._observation_window(obs_dict)
        if not self._actions:
            horizon = self.algo_config.horizon
            start = horizon.observation_horizon - 1
            chunk = self.sample_actions(window)[:, start : start + horizon.action_horizon]
            self._actions.extend(chunk.unbind(dim=1))
        return self._actions.popleft()

    def serialize(self) -> dict:
        """The trained weights and the EMA's state (robomimic stores this dict as a checkpoint's model)."""
        return dict(nets=self.nets.state_dict(), ema=self.ema.state_dict() if self.ema is not None else None)

    def deserialize(self, model_dict: dict) -> None:
        """
        Load model from a checkpoint.

        Args:
            model_dict (dict): a dictionary saved by self.serialize()
        """
        self.nets.load_state_dict(model_dict["nets"])
        if self.ema is not None:
            if model_dict.get("ema") is None:
                raise ValueError("the checkpoint holds no EMA weights, and its config enables algo.ema")
            self.ema.load_state_dict(model_dict["ema"])
            self._ema_current = False
