//! Board support for the STM32F407 (target only): pin map and HAL adapters.
